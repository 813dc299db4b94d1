"""The one place that bridges Python versions: import ``tomllib`` from here."""

try:  # Python >= 3.11
    # mypy checks as Python 3.10, which has no tomllib; the except branch is that case
    import tomllib  # type: ignore[import-not-found]
except ModuleNotFoundError:  # Python 3.10: the same parser, packaged as tomli
    import tomli as tomllib

__all__ = ["tomllib"]
