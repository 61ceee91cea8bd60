"""Shared pytest configuration (the test helpers are on sys.path through
pyproject.toml: [tool.pytest.ini_options] pythonpath)."""
