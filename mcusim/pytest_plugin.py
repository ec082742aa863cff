"""pytest plugin: test your firmware against mcusim the way this repository tests its own.

Active once mcusim is installed (entry point ``pytest11: mcusim``). It provides

* the fixture ``mcusim_sim``: a factory, ``sim = mcusim_sim("pro-mini", firmware=True,
  overrides={...})``, returning a fresh :class:`mcusim.Simulation`; at teardown every simulation
  it made is closed, and one that never ran is discarded (its firmware tasks dropped);
* the option ``--mcusim-vcd DIR``: each simulation made by the fixture that ran writes a VCD
  into DIR, named after the test's node id;
* the fixture ``mcusim_mavlink``: ``gcs = mcusim_mavlink(sim)`` gives a test a pymavlink ground
  station on the firmware's MAVLink UART, in simulated time (:class:`mcusim.mavlink.MavlinkClient`);
* the helpers of :mod:`mcusim.testing`, re-exported: ``wait_until``, ``wait_for_pin``,
  ``run_for``, ``SimTimeout``.

It is light at pytest start: the peripheral, plant and firmware models (and numpy) are imported
only when the fixture makes its first simulation.
"""

from __future__ import annotations

import contextlib
import hashlib
import re
from pathlib import Path

import pytest

from mcusim.testing import SimTimeout, run_for, wait_for_pin, wait_until

__all__ = ["SimTimeout", "mcusim_mavlink", "mcusim_sim", "run_for", "vcd_filename", "wait_for_pin", "wait_until"]

_MAX_STEM = 180


def pytest_addoption(parser):
    group = parser.getgroup("mcusim", "mcusim simulations")
    group.addoption(
        "--mcusim-vcd", metavar="DIR", default=None, dest="mcusim_vcd",
        help="write a VCD trace of every simulation made by the mcusim_sim fixture into DIR, "
             "one file per simulation, named after the test node id")
    group.addoption(
        "--mcusim-engine", choices=("fast", "reference"), default=None, dest="mcusim_engine",
        help="the engine of every simulation the mcusim_sim fixture makes (default: mcusim.load's, fast)")


def pytest_report_header(config):
    vcd_dir = config.getoption("mcusim_vcd", None)
    if vcd_dir:
        return f"mcusim: VCD traces to {_vcd_dir(config, vcd_dir)}"
    return None


def vcd_filename(nodeid: str, index: int = 1) -> str:
    """The VCD file name for the ``index``-th simulation of a test: the node id with ``::`` as
    ``__`` and anything but letters, digits, ``.``, ``_``, ``-`` as ``_``
    (``tests/test_fw.py::test_step[10]`` -> ``tests_test_fw.py__test_step_10.vcd``); the second
    and later simulations of one test get ``-2``, ``-3``...; a very long id is shortened with a hash,
    and so is one whose mapping loses what tells it from another id of the same test (a space,
    ``+``, ``/`` or dots in a parameter: ``test_a[a b]`` -> ``..._test_a_a_b-<6 hex>.vcd``). Ids of
    different tests that differ only by the mapped characters (``test_step[10]`` and a test
    named ``test_step_10``) still share a name."""
    raw = re.sub(r"[^A-Za-z0-9._-]+", "_", nodeid.replace("::", "__"))
    stem = raw.strip("_.") or "test"
    head, bracket, param = nodeid.partition("[")
    # a mapping that loses what tells two ids apart (``[a b]`` and ``[a_b]``, ``[+1]`` and ``[1]``,
    # ``[..]`` and ``[]``) gets a hash of the id, so that no test's trace overwrites another's
    ident = param[:-1]
    lossy = bool(re.search(r"[^A-Za-z0-9._/:-]", head) or stem != raw.rstrip("_") or (bracket and (
        not param.endswith("]") or not ident or re.search(r"[^A-Za-z0-9._-]", ident) or ident.strip("._") != ident)))
    if lossy and len(stem) <= _MAX_STEM:
        stem = f"{stem}-{hashlib.sha1(nodeid.encode()).hexdigest()[:6]}"
    if len(stem) > _MAX_STEM:
        digest = hashlib.sha1(nodeid.encode()).hexdigest()[:10]
        stem = f"{stem[:_MAX_STEM - 11]}-{digest}"
    suffix = f"-{index}" if index > 1 else ""
    return f"{stem}{suffix}.vcd"


def _vcd_dir(config, value) -> Path:
    path = Path(value).expanduser()
    if not path.is_absolute():      # relative to where pytest was started, not to a test's cwd
        path = Path(config.invocation_params.dir) / path
    return path


@pytest.fixture
def mcusim_sim(request):
    """A factory of simulations: ``mcusim_sim(board, firmware=True, overrides=None, **kw)`` is
    ``mcusim.load(...)``; every simulation it made is closed at teardown (and discarded if it
    never ran). With ``--mcusim-vcd DIR`` each one that ran also writes ``DIR/<node id>.vcd``
    (one that never ran leaves none: it would hold the header alone)."""
    vcd_option = request.config.getoption("mcusim_vcd", None)
    vcd_dir = _vcd_dir(request.config, vcd_option) if vcd_option else None
    made = []
    vcd_paths = {}              # id(sim) -> the VCD it writes

    def factory(board: str, firmware: bool = True, overrides: dict | None = None, **kw):
        # imported here, not at the top: keeps pytest start free of the models
        from mcusim.sim import load

        engine = request.config.getoption("mcusim_engine", None)
        if engine is not None:
            kw.setdefault("engine", engine)
        sim = load(board, firmware=firmware, overrides=overrides, **kw)
        made.append(sim)
        if vcd_dir is not None:
            vcd_dir.mkdir(parents=True, exist_ok=True)
            path = vcd_dir / vcd_filename(request.node.nodeid, len(made))
            sim.trace_vcd(path)
            vcd_paths[id(sim)] = path
        return sim

    factory.simulations = made
    yield factory

    with contextlib.ExitStack() as stack:   # every simulation is finished even if one fails
        for sim in made:
            stack.callback(_finish, sim, vcd_paths.get(id(sim)))


@pytest.fixture
def mcusim_mavlink():
    """A factory of ground stations: ``mcusim_mavlink(sim, **kw)`` is a
    :class:`mcusim.mavlink.MavlinkClient` on the MAVLink UART of ``sim``'s firmware (``kw``:
    ``system``, ``component``, ``heartbeat_hz``). ``gcs.mav`` is pymavlink's ``MAVLink`` object
    (``gcs.mav.command_long_send(...)``), ``gcs.recv_match(type, condition, timeout)`` runs the
    simulation until a matching message arrives."""

    def factory(sim, **kw):
        from mcusim.mavlink import MavlinkClient, mavlink_port

        uart, member = mavlink_port(sim)
        return MavlinkClient(sim, uart, member=member, **kw)

    return factory


def _finish(sim, vcd_path=None) -> None:
    never_ran = sim.kernel.now == 0 and sim.kernel.events == 0   # its tasks never started
    try:
        sim.close()
    finally:
        if never_ran:
            sim.discard()
            if vcd_path is not None and vcd_path.exists():
                vcd_path.unlink()
