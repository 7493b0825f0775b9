"""Helpers shared by the test modules, imported as `from tests.helpers.NAME import ...`."""
