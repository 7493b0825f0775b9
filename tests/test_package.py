"""Packaging: one import name, lazy extension, a clear message when the build is missing."""

from __future__ import annotations

import subprocess
import sys

from tests.helpers.paths import REPO


def run_python(code: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True)


def test_only_edgedog_is_importable_outside_the_repository(tmp_path):
    result = run_python(
        "import importlib.util as u, edgedog.renderer, edgedog.app;"
        "print(u.find_spec('app'), u.find_spec('renderer'));"
        "print(edgedog.renderer.__file__); print(edgedog.app.__file__)",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    specs, renderer_file, app_file = result.stdout.splitlines()
    assert specs == "None None"
    assert renderer_file == str(REPO / "renderer" / "__init__.py")
    assert app_file == str(REPO / "app" / "__init__.py")


def test_importing_edgedog_loads_neither_torch_nor_the_extension(tmp_path):
    result = run_python(
        "import sys, edgedog, edgedog.renderer, edgedog.scenes, edgedog.metrics, edgedog.cli;"
        "print('torch' in sys.modules, 'edgedog.renderer._C' in sys.modules)",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "False"]


def test_extension_is_built_with_openmp():
    from edgedog.renderer import load_extension

    info = load_extension().build_info()
    assert info["openmp"] is True
    assert info["max_threads"] >= 1


def test_missing_extension_gives_one_line_on_how_to_build(tmp_path):
    # A None entry in sys.modules makes the import fail as if the .so were absent.
    result = run_python(
        "import sys; sys.modules['edgedog.renderer._C'] = None\n"
        "from edgedog.cli import main\n"
        "from edgedog.renderer import load_extension, ExtensionNotBuiltError\n"
        "try:\n    load_extension()\nexcept ExtensionNotBuiltError as e:\n    print(e)\n",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    message = result.stdout.strip()
    assert "\n" not in message
    assert "not built" in message and "make build" in message


def test_every_package_folder_is_listed_for_the_wheel():
    import tomllib

    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(setuptools["packages"])
    for name, folder in setuptools["package-dir"].items():
        for init in (REPO / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(REPO / folder).parts
            assert ".".join((name, *parts)) in listed, f"{init.parent} is not in pyproject's packages"
