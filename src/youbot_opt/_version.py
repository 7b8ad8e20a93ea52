"""The package version, read by the build backend (pyproject.toml) and the file headers."""

__version__ = "0.1.0"
