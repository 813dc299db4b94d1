"""The errors and warnings spiralbayes raises, as one small hierarchy users can catch.

Every user-facing error subclasses :class:`SpiralbayesError`; those about the user's input also
subclass :class:`ValueError` (and missing files :class:`FileNotFoundError`), so code written
against the built-in exceptions keeps working::

    try:
        result = sb.scan(vis, disc, templates, r_p=radii)
    except sb.exceptions.ResumeMismatchError:
        ...  # the checkpoint belongs to other inputs
    except sb.exceptions.InputError as exc:
        print(exc)  # one line naming the field and the fix

Warnings have their own categories so they can be filtered (``warnings.simplefilter``).
"""

from __future__ import annotations

__all__ = [
    "SpiralbayesError",
    "InputError",
    "ConfigError",
    "DataFileError",
    "MissingFileError",
    "ResumeMismatchError",
    "ImageGridError",
    "ConvergenceError",
    "MissingDependencyError",
    "SpiralbayesWarning",
    "ConvergenceWarning",
    "DataWarning",
    "AccuracyWarning",
]


class SpiralbayesError(Exception):
    """Base class of every error raised on purpose by spiralbayes."""


class InputError(SpiralbayesError, ValueError):
    """A parameter, an array or a file's content is not acceptable; the message says the fix."""


class ConfigError(InputError):
    """A configuration file or dict has an unknown key or a bad value."""


class DataFileError(InputError):
    """A file exists but cannot be read as what it should be (truncated, wrong kind, corrupt)."""


class MissingFileError(SpiralbayesError, FileNotFoundError):
    """A file or directory the call needs does not exist."""


class ResumeMismatchError(InputError):
    """A checkpoint or chain file was written for other inputs than the run that found it."""


class ImageGridError(InputError):
    """An image grid too coarse or too small for the baselines it is sampled at."""


class ConvergenceError(SpiralbayesError, RuntimeError):
    """A chain failed its convergence test and the policy is ``"raise"``."""


class MissingDependencyError(SpiralbayesError, ImportError):
    """An optional dependency is not installed; the message gives the ``pip install`` line."""


class SpiralbayesWarning(UserWarning):
    """Base class of spiralbayes' warnings."""


class ConvergenceWarning(SpiralbayesWarning):
    """A chain failed its convergence test and the policy is ``"warn"``."""


class DataWarning(SpiralbayesWarning):
    """The data look suspicious (units, weights) but could be right."""


class AccuracyWarning(SpiralbayesWarning):
    """A numerical error estimate exceeds its tolerance."""
