"""The GTKWave layout written with a VCD names every variable as GTKWave names it.

GTKWave reads a VCD variable whose name holds its hierarchy delimiter (the plant's
``motor1.angle_rad`` in scope ``board.plant``) as an escaped name, ``board.plant.\\motor1.angle_rad``;
a layout naming it without the backslash shows nothing for it, without a warning (GTKWave 3.3.118:
22 of the quick start's 28 signals were shown, none of the plant's).
"""

import os
import re
import shutil
import subprocess

import pytest

from mcusim.cli import main


def _vcd_names(vcd: str) -> set[str]:
    """Every variable of the VCD header as GTKWave names it: scope path, then the name, escaped
    with a backslash where it holds a dot."""
    names, scopes = set(), []
    with open(vcd) as f:
        header = f.read().split("$enddefinitions")[0].splitlines()
    for line in header:
        tok = line.split()
        if tok[:1] == ["$scope"]:
            scopes.append(tok[2])
        elif tok[:1] == ["$upscope"]:
            scopes.pop()
        elif tok[:1] == ["$var"]:
            name = tok[4]
            names.add(".".join(scopes) + "." + ("\\" + name if "." in name else name))
    return names


def _layout_names(gtkw: str) -> list[str]:
    with open(gtkw) as f:
        lines = [line.strip() for line in f]
    return [line for line in lines if line and not re.match(r"[\[@\-*]", line)]


@pytest.mark.parametrize("board", ["nucleo-f746", "elementall"])
def test_the_layout_names_every_vcd_variable_as_gtkwave_does(tmp_path, board):
    vcd = tmp_path / "run.vcd"
    assert main(["run", board, "--duration", "1ms", "--vcd", str(vcd), "-q"]) == 0
    names = _layout_names(str(tmp_path / "run.gtkw"))
    assert sorted(names) == sorted(_vcd_names(str(vcd)))
    assert any("plant.\\" in n and n.endswith(".angle_rad") for n in names)


@pytest.mark.skipif(not (shutil.which("gtkwave") and shutil.which("xvfb-run")), reason="needs gtkwave and xvfb")
def test_gtkwave_shows_every_signal_of_the_quick_start_layout(tmp_path):
    vcd = tmp_path / "run.vcd"
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--vcd", str(vcd), "-q"]) == 0
    script = tmp_path / "shown.tcl"
    script.write_text('set n [gtkwave::getDisplayedSignals]\nputs "DISPLAYED [llength $n]"\n'
                      'puts "FACS [gtkwave::getNumFacs]"\ngtkwave::/File/Quit\n')
    out = subprocess.run(["xvfb-run", "-a", "gtkwave", "-S", str(script), "run.gtkw"], cwd=tmp_path, check=False,
                         capture_output=True, text=True, timeout=120, env={**os.environ, "LC_ALL": "C"}).stdout
    shown = int(re.search(r"DISPLAYED (\d+)", out).group(1))
    facs = int(re.search(r"FACS (\d+)", out).group(1))
    assert shown == facs == len(_vcd_names(str(vcd)))
