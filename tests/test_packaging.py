"""Packaging (issue 11): the installed distribution claims the import name ``mcusim`` only (the
repository's periph/, firmware/, boards/ and scenarios/ become mcusim.periph, mcusim.fw,
mcusim.boards and mcusim.scenarios), and a built wheel works on its own: boards found, scenarios
nameable, the command line runs."""

import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MAPPING = {"mcusim": "mcusim", "mcusim.periph": "periph", "mcusim.fw": "firmware", "mcusim.boards": "boards",
           "mcusim.scenarios": "scenarios"}


def _pyproject():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_the_top_level_folders_are_mapped_under_mcusim():
    tool = _pyproject()["tool"]["setuptools"]
    assert tool["package-dir"] == MAPPING


def test_every_package_folder_is_listed():
    listed = set(_pyproject()["tool"]["setuptools"]["packages"])
    found = set()
    for package, folder in MAPPING.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder)
            found.add(".".join([package, *rel.parts]))
    assert found == listed


def test_no_module_imports_the_repositorys_folders_by_their_top_level_names():
    pattern = re.compile(r"^\s*(from|import)\s+(periph|firmware|boards|scenarios)\b", re.MULTILINE)
    bad = []
    for folder in ("mcusim", "periph", "firmware", "tests", "benchmarks"):
        for path in (ROOT / folder).rglob("*.py"):
            bad += [f"{path.relative_to(ROOT)}: {m.group(0).strip()}" for m in pattern.finditer(path.read_text())]
    readme = (ROOT / "README.md").read_text()
    bad += [f"README.md: {m.group(0).strip()}" for m in pattern.finditer(readme)]
    assert bad == []


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    try:
        import setuptools  # noqa: F401  (the build backend, used without isolation: no network)
    except ImportError:
        pytest.skip("setuptools is not installed")
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(out), str(ROOT)], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = out.glob("mcusim-*.whl")
    return whl


def test_the_wheel_holds_mcusim_only_with_its_data(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"mcusim"}
    for needed in ("mcusim/boards/nucleo-f746.toml", "mcusim/scenarios/step_response.toml",
                   "mcusim/periph/stm32/tim.py", "mcusim/fw/controlmotor/app.py", "mcusim/cli.py",
                   "mcusim/fw/controlmotor_c/controlmotor.elf", "mcusim/fw/controlmotor_c/controlmotor.topics.toml",
                   "mcusim/fw/controlmotor_c/controlmotor_thesis.elf",
                   "mcusim/fw/controlmotor_c/controlmotor_thesis.topics.toml"):
        assert needed in names, needed


def test_the_installed_wheel_runs_on_its_own(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    work = tmp_path / "work"                  # not the repository: nothing to find by accident
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}

    def py(*args):
        return subprocess.run([sys.executable, "-P", *args], cwd=work, env=env, capture_output=True,
                              text=True, timeout=120, check=False)

    r = py("-c", "import importlib.util, mcusim, mcusim.periph.stm32.tim as t, mcusim.boards as b; "
                 "print(mcusim.__file__); print(t.__file__); print(b.__file__); "
                 "print([importlib.util.find_spec(n) for n in ('periph', 'firmware', 'boards')])")
    lines = r.stdout.splitlines()
    assert r.returncode == 0, r.stderr
    assert all(line.startswith(str(site)) for line in lines[:3]), lines
    assert lines[3] == "[None, None, None]"
    r = py("-m", "mcusim", "boards")
    assert r.returncode == 0 and "nucleo-f746" in r.stdout and "elementall" in r.stdout, r.stderr
    r = py("-m", "mcusim", "run", "nucleo-f746", "--scenario", "step_response", "--duration", "2ms",
           "--vcd", "s.vcd", "--summary", "s.json", "-q")
    assert r.returncode in (0, 1) and "Traceback" not in r.stderr, r.stderr      # 1: the end checks come later
    assert (work / "s.vcd").is_file() and (work / "s.gtkw").is_file() and (work / "s.json").is_file()
    assert "step_response.toml" in r.stdout
    r = py("-c", "import sys; sys.modules['matplotlib'] = None; from mcusim.cli import main; "
                 "sys.exit(main(['run', 'pro-mini', '--duration', '1ms', '--plot', 'p.png']))")
    assert r.returncode == 2 and "pip install 'mcusim[plot]'" in r.stderr and not (work / "p.png").exists()
