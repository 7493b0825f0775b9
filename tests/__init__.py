"""The test suite. Its helpers (tests.helpers) are imported by name, the repository root on
sys.path (pyproject.toml: [tool.pytest.ini_options] pythonpath)."""
