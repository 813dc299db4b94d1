"""Importing CASA: a clear install hint without it; offline, nothing written to HOME or the cwd with it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from spiralbayes._casa import INSTALL_HINT, _configure, casa_available, import_casa
from spiralbayes.exceptions import MissingDependencyError


def test_missing_casa_names_the_extra(monkeypatch):
    for name in ("casadata", "casaconfig", "casaconfig.config"):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(MissingDependencyError, match=r'pip install "spiralbayes\[casa\]"'):
        _configure(os.devnull, False)
    for name in ("casatools", "casatasks"):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ImportError, match=r"spiralbayes\[casa\]"):
        import_casa()
    assert "spiralbayes[casa]" in INSTALL_HINT


def test_compare_command_without_casa_fails_fast_with_the_hint(monkeypatch, tmp_path, caplog):
    from spiralbayes.cli import main

    for name in ("casatools", "casatasks", "casadata"):
        monkeypatch.setitem(sys.modules, name, None)
    config = tmp_path / "c.toml"
    config.write_text('[data]\npath = "missing.h5"\n')
    assert main(["compare", str(config)]) == 2
    assert "spiralbayes[casa]" in caplog.text


@pytest.mark.casa
def test_offline_import_touches_neither_home_nor_cwd(tmp_path):
    if not casa_available():
        pytest.skip('CASA is not installed (pip install -e ".[test,casa]")')
    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir()
    cwd.mkdir()
    code = textwrap.dedent("""
        from spiralbayes._casa import import_casa
        casatools, casatasks = import_casa()
        me = casatools.measures()
        frame = me.doframe(me.observatory("ALMA"))
        print("ALMA", me.observatory("ALMA")["m0"]["value"])
    """)
    env = {**os.environ, "HOME": str(home), "MPLCONFIGDIR": str(tmp_path / "mpl")}
    env.pop("SPIRALBAYES_CASA_CONFIG", None)
    out = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "ALMA" in out.stdout
    assert list(home.iterdir()) == [] and list(cwd.iterdir()) == []
