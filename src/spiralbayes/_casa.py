"""Import CASA (casatools, casatasks) ready to run offline, without touching the user's CASA files.

CASA 6 reads its configuration once, when ``casatools`` is first imported: ``import casatools``
runs ``casaconfig.config``, which evaluates a site configuration (``$CASASITECONFIG``, a
``casasiteconfig`` module) and the user's ``~/.casa/config.py`` and then reads *module
attributes* such as ``measurespath`` and ``measures_auto_update``. Without a configuration the
import fails ("measures data is not available") unless ``~/.casa/data`` holds the measures
tables, and by default it tries to update them over the network.

:func:`import_casa` sets those attributes on ``casaconfig.config`` *before* the first import
of ``casatools``: the measures and data path become the ``casadata`` package's folder
(``casadata.datapath``, installed with ``pip install "spiralbayes[casa]"``), both automatic
updates are switched off, and the CASA log goes to the file given (``os.devnull`` by default)
instead of ``casa-<date>.log`` in the working directory. Nothing is written to ``~/.casa``.
Pass ``respect_user_config=True`` (or set the environment variable
``SPIRALBAYES_CASA_CONFIG=user``) to keep the values of a ``~/.casa/config.py`` or site
configuration when one was loaded. If ``casatools`` was already imported (by the user, or by
an earlier call) its configuration cannot be changed any more: it is used as it is.

(The mechanism was worked out on CASA 6.7.0.31 with casaconfig 1.5.2: ``casaconfig.config``
exposes ``load_success()``, the list of configuration files it evaluated.)
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import sys

from .exceptions import MissingDependencyError

__all__ = ["INSTALL_HINT", "casa_available", "casa_log", "import_casa", "working_directory"]

log = logging.getLogger(__name__)

INSTALL_HINT = 'pip install "spiralbayes[casa]"'
_ENV = "SPIRALBAYES_CASA_CONFIG"


def casa_available() -> bool:
    """True if casatools, casatasks and casadata can be imported (nothing is imported)."""
    if "casatools" in sys.modules and "casatasks" in sys.modules:
        return True
    return all(importlib.util.find_spec(name) is not None for name in ("casatools", "casatasks", "casadata"))


def _configure(logfile: str, respect_user_config: bool) -> None:
    try:
        import casadata
        import casaconfig.config as cfg
    except ImportError as exc:
        raise MissingDependencyError(
            f"CASA is not installed ({exc.name or exc}): {INSTALL_HINT} (casatools, casatasks and casadata, ~2 GB)"
        ) from None
    loaded = [f for f in getattr(cfg, "load_success", list)()
              if not f.replace("\\", "/").endswith("casaconfig/config.py")]
    if respect_user_config and loaded:
        log.info("CASA: keeping the configuration of %s", ", ".join(loaded))
    else:
        cfg.measurespath = casadata.datapath
        cfg.datapath = [casadata.datapath]
        cfg.measures_auto_update = False
        cfg.data_auto_update = False
        log.debug("CASA: measures from %s, automatic updates off", casadata.datapath)
    cfg.logfile = logfile


def import_casa(*, logfile: str | os.PathLike | None = None, respect_user_config: bool | None = None):
    """``(casatools, casatasks)``, imported and configured to run offline from ``casadata``.

    Parameters
    ----------
    logfile : path, optional
        The CASA log (default ``os.devnull``). Only used on the first import in a process;
        use :func:`casa_log` to redirect the log of later calls.
    respect_user_config : bool, optional
        Keep a loaded ``~/.casa/config.py`` / site configuration instead of pointing CASA at
        ``casadata`` (default: from ``SPIRALBAYES_CASA_CONFIG=user``, else False).

    Raises
    ------
    MissingDependencyError
        CASA is not installed; the message gives ``pip install "spiralbayes[casa]"``.
    """
    if respect_user_config is None:
        respect_user_config = os.environ.get(_ENV, "").strip().lower() == "user"
    if "casatools" not in sys.modules:
        _configure(os.fspath(logfile) if logfile else os.devnull, bool(respect_user_config))
    else:
        log.debug("CASA: casatools was already imported; its configuration is used as it is")
    try:
        import casatools
        import casatasks
    except ImportError as exc:
        raise MissingDependencyError(f"CASA could not be imported ({exc}): {INSTALL_HINT}") from None
    return casatools, casatasks


@contextlib.contextmanager
def casa_log(path: str | os.PathLike):
    """Send the CASA log to ``path`` inside the block (the previous log file is restored after)."""
    _, casatasks = import_casa()
    sink = casatasks.casalog
    previous = sink.logfile()
    sink.setlogfile(os.fspath(path))
    try:
        yield path
    finally:
        sink.setlogfile(previous or os.devnull)


@contextlib.contextmanager
def working_directory(path: str | os.PathLike):
    """Run a CASA task inside ``path``: tclean and simobserve leave scratch files in the cwd.

    Changes the process's working directory for the duration of the block (not thread-safe).
    """
    previous = os.getcwd()
    os.makedirs(path, exist_ok=True)
    os.chdir(path)
    try:
        yield path
    finally:
        os.chdir(previous)
