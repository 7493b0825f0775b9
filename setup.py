"""Builds the C++ CPU extension `edgedog.renderer._C` from csrc/.

Everything else (metadata, packages, console script) is in pyproject.toml. Build with
`pip install --no-build-isolation -e .` so the pinned torch of the environment is used.
"""
from pathlib import Path

from setuptools import setup
from torch.utils.cpp_extension import BuildExtension, CppExtension

ROOT = Path(__file__).parent
SOURCES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "csrc").glob("*.cpp"))

setup(
    ext_modules=[
        CppExtension(
            name="edgedog.renderer._C",
            sources=SOURCES,
            include_dirs=[str(ROOT / "csrc")],
            # fp-contract off: forward and backward must compute bit-identical alphas.
            extra_compile_args=["-O3", "-fopenmp", "-std=c++17", "-ffp-contract=off"],
            extra_link_args=["-fopenmp"],
        )
    ],
    cmdclass={"build_ext": BuildExtension},
)
