"""Every example of the README, the docs and `--help` is executed (issue 11).

Commands are run as written, in a scratch folder that holds the repository's `boards/` and
`scenarios/`, with one documented change: a `--duration` is appended (an option given twice takes
its last value, README "Command line"), so that slow examples run in a fraction of a second. An
example whose comment says "exit status N" must exit with N; the others with 0 (a shortened
scenario may also exit 1: its expectations after the end are not reached, as documented)."""

import re
import shlex
from pathlib import Path

import pytest

import mcusim
from mcusim.cli import _parser, main

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", ROOT / "docs" / "scenarios.md", ROOT / "docs" / "boards.md", ROOT / "docs" / "mavlink.md",
        ROOT / "docs" / "firmware.md"]
SHORT = {"default": "20ms", "exit1": "300ms"}      # long enough for ciaa-edu to find no module


def _blocks(text, lang):
    return re.findall(rf"```{lang}\n(.*?)```", text, re.DOTALL)


def _commands():
    """(where, command line, expected exit status) of every `mcusim ...` example."""
    out = []
    for doc in DOCS:
        for block in _blocks(doc.read_text(), "sh"):
            for raw in block.splitlines():
                line = raw.strip()
                if "&& mcusim " in line:                  # the quick start: install && run
                    line = line.split("&& ", 1)[1]
                if not line.startswith("mcusim ") or "my-board" in line:   # my-board: the walk-through test
                    continue
                cmd, _, comment = line.partition("#")
                if re.search(r"\b(BOARD|FILE)\b", cmd):   # the synopsis, not an example
                    continue
                m = re.search(r"exit status (\d)", comment)
                out.append((f"{doc.name}: {cmd.strip()}", cmd.strip(), int(m.group(1)) if m else 0))
    for name, sub in _parser()._subparsers._group_actions[0].choices.items():
        for line in (sub.epilog or "").splitlines():
            if line.startswith("  mcusim "):
                out.append((f"mcusim {name} --help: {line.strip()}", line.strip(), 0))
    return out


COMMANDS = _commands()


def test_the_examples_are_found():
    names = " ".join(c for _, c, _ in COMMANDS)
    for needle in ("mcusim run nucleo-f746 --vcd nucleo-f746.vcd", "mcusim run ciaa-edu", "--strict",
                   "mcusim bench", "mcusim trace", "--scenario", "mcusim boards --kinds"):
        assert needle in names, needle
    assert len(COMMANDS) >= 25


@pytest.mark.parametrize("where, cmd, expected", COMMANDS, ids=[w for w, _, _ in COMMANDS])
def test_example_command_runs_as_documented(tmp_path, monkeypatch, capsys, where, cmd, expected):
    for folder in ("boards", "scenarios", "firmware"):
        (tmp_path / folder).symlink_to(ROOT / folder)
    monkeypatch.chdir(tmp_path)
    argv = shlex.split(cmd)[1:]
    assert ">" not in argv
    # a compiled image's scenario runs in full (a few seconds): shortened, its failures would
    # hide among the expectations an early end cannot reach (it once failed "set point taken")
    full = "--scenario" in argv and "--firmware" in argv
    if argv[0] in ("run", "trace", "bench") and not full:
        argv += ["--duration", SHORT["exit1" if expected == 1 else "default"]]
    if argv[0] == "bench":
        argv += ["--repeat", "1"]
    rc = main(argv)
    err = capsys.readouterr().err
    allowed = {expected, 1} if "--scenario" in argv and not full else {expected}
    assert rc in allowed, (cmd, rc, err)
    assert "Traceback" not in err and ("error:" not in err or expected == 1), err
    for opt in ("--vcd", "--csv", "--summary", "--plot", "--json", "--register-log"):
        if opt in argv:
            assert (tmp_path / argv[argv.index(opt) + 1]).is_file(), opt


@pytest.mark.parametrize("doc, least", [("README.md", 2), ("docs/firmware.md", 1)])
def test_python_examples_run(doc, least, monkeypatch):
    monkeypatch.chdir(ROOT)                                  # paths in the examples are the repository's
    text = (ROOT / doc).read_text()
    blocks = _blocks(text, "python")
    assert len(blocks) >= least
    for block in blocks:
        ns: dict = {}
        exec(compile(block, doc, "exec"), ns)                # noqa: S102 (the docs' own examples)
        for value in ns.values():
            if isinstance(value, mcusim.Simulation):
                value.close()


def test_every_set_example_of_the_readme_is_accepted_by_a_shipped_board():
    text = (ROOT / "README.md").read_text()
    pairs = set(re.findall(r"--set ([^\s`=]+)=([^\s`]+)", text)) | set(
        re.findall(r"`(firmware\.[a-z_]+)=([^\s`]+)`", text))
    assert ("bridgeA.I_ocd", "4.0") in pairs and len(pairs) >= 15
    boards = mcusim.board.board_names()
    for key, value in sorted(pairs):
        if key in ("KEY",):
            continue
        if key.startswith("'") and value.endswith("'"):     # shell quotes: --set 'KEY="text"'
            key, value = key[1:], value[:-1]
        errors = []
        for board in boards:
            try:
                sim = mcusim.load(board, overrides={key: value})
            except mcusim.ConfigError as exc:
                errors.append(f"{board}: {exc}")
                continue
            sim.discard()
            break
        else:
            pytest.fail(f"--set {key}={value} is accepted by no shipped board: {errors}")


def test_the_repository_points_to_nothing_outside_it():
    """README, docs, profiles and code name no path outside the repository (issue 11)."""
    bad = re.compile("|".join((r"\.\./" + "shared", "/" + "work/", r"reference/[a-z_0-9]+\.md",
                               r"(?<!docs/)\bplants\.md\b")))   # docs/plants.md is the repository's own
    offenders = []
    for path in ROOT.rglob("*"):
        if path.suffix in (".py", ".md", ".toml", ".txt", ".cfg") and ".git" not in path.parts \
                and "build" not in path.parts and path.is_file():
            for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if bad.search(line):
                    offenders.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert offenders == []
