"""No output of a command may overwrite a file the command reads: the board's profile (a shipped
one named by its name too), a system's member profiles, the ``--firmware`` image and its topic map,
the scenario. Each is refused before the run with one line and exit 2 (a review wrote a VCD over
the shipped nucleo-f746 profile, and a summary over the ELF it ran, with exit 0)."""

import shutil
from pathlib import Path

import pytest

from mcusim.board import profile_file
from mcusim.cli import main


def _one_error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mcusim: error:"), err
    return err[0]


def _kept(path: Path):
    """The file's bytes, to check (and put back, were the rule broken) after the command."""
    return path.read_bytes()


@pytest.mark.parametrize("option", ["--vcd", "--csv", "--summary", "--register-log"])
def test_an_output_over_the_shipped_profile_named_by_its_board_name_is_refused(capsys, option):
    shipped = profile_file("nucleo-f746")
    before = _kept(shipped)
    try:
        msg = _one_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", "-q", option, str(shipped)])
    finally:
        if shipped.read_bytes() != before:
            shipped.write_bytes(before)
    assert "input of this run" in msg and shipped.read_bytes() == before


def test_an_output_over_a_system_members_profile_is_refused(capsys):
    member = profile_file("pro-mini")
    before = _kept(member)
    try:
        msg = _one_error(capsys, ["run", "elementall", "--duration", "1ms", "-q", "--summary", str(member)])
    finally:
        if member.read_bytes() != before:
            member.write_bytes(before)
    assert "input of this run" in msg


def test_an_output_over_the_firmware_image_or_its_topic_map_is_refused(tmp_path, capsys):
    src = Path(__file__).resolve().parents[1] / "firmware" / "controlmotor_c"
    elf = tmp_path / "app.elf"
    shutil.copy(src / "controlmotor.elf", elf)
    shutil.copy(src / "controlmotor.topics.toml", tmp_path / "app.topics.toml")
    image = elf.read_bytes()
    for target in (elf, tmp_path / "app.topics.toml"):
        msg = _one_error(capsys, ["run", "nucleo-f746", "--firmware", str(elf), "--duration", "1ms", "-q",
                                  "--summary", str(target)])
        assert "input of this run" in msg
    assert elf.read_bytes() == image


def test_bench_refuses_its_json_over_the_profile_and_on_standard_output(tmp_path, capsys):
    board = tmp_path / "b.toml"
    shutil.copy(profile_file("pro-mini"), board)
    assert "input of this run" in _one_error(capsys, ["bench", str(board), "--json", str(board)])
    assert "give a file name" in _one_error(capsys, ["bench", "pro-mini", "--json", "-"])
    assert not Path("-").exists()


@pytest.mark.parametrize("option, name", [("--summary", "s.json"), ("--vcd", "t.vcd"), ("--csv", "t.csv")])
def test_an_output_given_as_a_symbolic_link_is_written_through_it(tmp_path, option, name):
    """The file the link names is the one replaced, and the link stays (it had been replaced by a
    plain file, the target left as it was)."""
    from mcusim.cli import main
    (tmp_path / "keep").mkdir()
    real = tmp_path / "keep" / name
    real.write_text("old")
    link = tmp_path / name
    link.symlink_to(Path("keep") / name)
    assert main(["run", "nucleo-f746", "--duration", "5ms", "--quiet", option, str(link)]) == 0
    assert link.is_symlink() and real.read_text() != "old" and real.stat().st_size > 100


def test_an_output_naming_an_open_descriptor_is_written_into_a_pipe_and_refused_on_a_regular_file(tmp_path, capsys):
    """``--json /dev/stdout``: /dev/stdout -> /proc/self/fd/1 had been replaced by a plain file
    holding the JSON. Onto a pipe the output goes through the descriptor; onto a regular file
    (a shell redirection) opening it again would start at offset 0, truncating or overwriting
    what is there, so it is refused, naming the way out."""
    import os
    import threading

    from mcusim.cli import main
    sink = tmp_path / "stdout.txt"
    with open(sink, "w") as f:
        f.write("kept\n")
        f.flush()
        link = tmp_path / "stdout"
        link.symlink_to(f"/proc/self/fd/{f.fileno()}")
        assert main(["bench", "nucleo-f746", "--duration", "5ms", "--repeat", "1", "--quiet",
                     "--json", str(link)]) == 2
    assert "open file descriptor on a regular file" in capsys.readouterr().err
    assert link.is_symlink() and sink.read_text() == "kept\n"
    r, w = os.pipe()
    got = []
    reader = threading.Thread(target=lambda: got.append(os.fdopen(r).read()))
    reader.start()
    try:
        assert main(["bench", "nucleo-f746", "--duration", "5ms", "--repeat", "1", "--quiet",
                     "--json", f"/proc/self/fd/{w}"]) == 0
    finally:
        os.close(w)
        reader.join(30)
    assert '"realtime_factor"' in got[0]
