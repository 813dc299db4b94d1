"""The one place that bridges Python versions: import ``tomllib`` from here."""

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the same parser, packaged as tomli
    import tomli as tomllib

__all__ = ["tomllib"]
