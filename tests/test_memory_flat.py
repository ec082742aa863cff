"""Memory stays flat in run length: the fast engine's caches (period plans, piece maps, power
tables) are bounded, and nothing accumulates per event without a trace asking for it."""

import subprocess
import sys

import pytest

# the quick start's run (the profile's [run.set]: both motors to new angles, then holding)
SCRIPT = """
import resource
from mcusim.cli import main
try:
    main(["run", "nucleo-f746", "--duration", "{seconds}s", "--quiet"])
except SystemExit as exc:
    assert not exc.code, exc.code
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def _peak_kb(seconds: float) -> int:
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(seconds=seconds)], check=True,
                         capture_output=True, text=True).stdout
    return int(out.split()[-1])


@pytest.mark.heavy
def test_a_10s_run_without_traces_peaks_within_15_percent_of_a_half_second_run():
    short, long_ = _peak_kb(0.5), _peak_kb(10.0)
    assert long_ <= 1.15 * short, (short, long_)
