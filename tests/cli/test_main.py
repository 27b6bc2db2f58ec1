"""The command line: the demo runs and reports its checks; errors are reported, not raised."""

from __future__ import annotations

import subprocess
import sys

from camkit.cli.main import main


def test_demo_prints_what_it_did(capsys):
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    assert "54 corners projected" in out
    # The round-trip figure printed is a real measurement and tiny.
    err = float(out.split("round trip ")[1].split(" px")[0])
    assert err < 1e-9


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "demo" in capsys.readouterr().out


def test_module_entry_point():
    proc = subprocess.run([sys.executable, "-m", "camkit", "--version"], capture_output=True, text=True,
                          check=False, timeout=120)
    assert proc.returncode == 0 and proc.stdout.startswith("camkit ")
