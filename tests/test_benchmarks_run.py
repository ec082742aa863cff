"""The benchmark scripts still run (not their figures: speed is never asserted), and the one that
switches the fast engine's shortcuts off and on leaves them on."""

import importlib.util
import sys
from pathlib import Path

from mcusim.engine import screening, served

ROOT = Path(__file__).resolve().parent.parent


def _load(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_bench_fast_paths_runs_each_case_both_ways_and_restores_the_switches(monkeypatch, capsys):
    mod = _load("bench_fast_paths")
    monkeypatch.setattr(mod, "CASES", [(name, switch, board, overrides, 0.01, 0.01)
                                       for name, switch, board, overrides, _, _ in mod.CASES])
    monkeypatch.setattr(sys, "argv", ["bench_fast_paths.py", "--repeat", "1"])
    held_states = screening.PeriodPlan._held_states
    mod.main()
    out = capsys.readouterr().out
    assert out.count(" with it, ") == len(mod.CASES)
    assert served.COUNT_MIN == 4 and screening.STUCK_ENDS is True and screening.MODAL is True
    assert screening.PeriodPlan._held_states is held_states
    assert "_held_states_on" not in vars(screening.PeriodPlan)
