"""Builds the extension `edgedog.renderer._C` from csrc/: the C++ CPU kernels always, and the CUDA
kernels (csrc/*.cu) when the environment's torch is a CUDA build with a CUDA toolkit beside it.

Everything else (metadata, packages, console script) is in pyproject.toml. Build with
`pip install --no-build-isolation -e .` so the pinned torch of the environment is used.
EDGEDOG_CUDA=0 forces a CPU-only build, EDGEDOG_CUDA=1 fails when CUDA cannot be built.
"""
import os
from pathlib import Path

import torch
from setuptools import setup
from torch.utils.cpp_extension import CUDA_HOME, BuildExtension, CppExtension, CUDAExtension

ROOT = Path(__file__).parent
CPP_SOURCES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "csrc").glob("*.cpp"))
CUDA_SOURCES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "csrc").glob("*.cu"))
# fp-contract off (and nvcc's fmad off): forward and backward must compute bit-identical alphas.
CXX_FLAGS = ["-O3", "-fopenmp", "-std=c++17", "-ffp-contract=off"]
NVCC_FLAGS = ["-O3", "-std=c++17", "--fmad=false", "--expt-relaxed-constexpr"]


def build_cuda() -> bool:
    """Whether to build the CUDA kernels: asked for by EDGEDOG_CUDA, else when torch and a toolkit allow."""
    wanted = os.environ.get("EDGEDOG_CUDA", "auto")
    possible = torch.version.cuda is not None and CUDA_HOME is not None
    if wanted == "1" and not possible:
        raise RuntimeError(f"EDGEDOG_CUDA=1, but torch {torch.__version__} has no CUDA "
                           "or no CUDA toolkit was found")
    return possible and wanted != "0"


if build_cuda():
    extension = CUDAExtension(
        name="edgedog.renderer._C",
        sources=CPP_SOURCES + CUDA_SOURCES,
        include_dirs=[str(ROOT / "csrc")],
        define_macros=[("EDGEDOG_WITH_CUDA", "1")],
        extra_compile_args={"cxx": CXX_FLAGS, "nvcc": NVCC_FLAGS},
        extra_link_args=["-fopenmp"],
    )
else:
    extension = CppExtension(
        name="edgedog.renderer._C",
        sources=CPP_SOURCES,
        include_dirs=[str(ROOT / "csrc")],
        extra_compile_args=CXX_FLAGS,
        extra_link_args=["-fopenmp"],
    )

setup(ext_modules=[extension], cmdclass={"build_ext": BuildExtension})
