"""The files a command writes: all checked before the run starts, and written so that a run that
fails or is interrupted leaves no half-written file posing as complete.

* Checked first: each path is writable (its folder exists and may be written; an existing file
  may be replaced; a folder is refused), no two outputs name the same file (the VCD's ``.gtkw``
  included), no output overwrites an input (the scenario or board file), and what an output
  needs is there (matplotlib for ``--plot``, a known image format).
* Written at the end (summary, plot, GTKWave layout, bench figures): to a hidden temporary file
  in the same folder, renamed over the final name once complete.
* Streamed during the run (VCD, CSV, register log): to ``<name>.part``, renamed to ``<name>``
  when the run completes. A run that fails leaves ``<name>.part`` (marked incomplete) and says so.

Special files (``/dev/null``, a FIFO, a terminal) are written directly.
"""

from __future__ import annotations

import os
import secrets
import stat

from .errors import ConfigError

PLOT_FORMATS = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def open_output(path, what: str, **kw):
    """``(path, file)``: ``path`` (a str or os.PathLike) opened for writing by a trace of the Python
    API (``what``: "VCD", "CSV", ...); ConfigError naming the path for anything that cannot be."""
    try:
        path = os.fspath(path)
    except TypeError:
        raise ConfigError(f"{what}: {path!r:.80} is not a file name (nor a file object)") from None
    if not path:
        raise ConfigError(f"{what}: an empty file name")
    if os.path.isdir(path):
        raise ConfigError(f"{what} {path}: is a folder; give a file name")
    try:
        return path, open(path, "w", **kw)
    except OSError as exc:
        raise ConfigError(f"{what} {path}: cannot write it ({exc.strerror or exc})") from None


def _special(path: str) -> bool:
    """An existing file that is not a regular file (a device, a FIFO): written in place."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


def _through_proc(path: str) -> bool:
    """Whether ``path`` names an open file of some process: in /proc or /dev/fd, or a chain of
    symbolic links through them (``/dev/stdout`` -> ``/proc/self/fd/1``). Never replaced."""
    for _ in range(40):
        if os.path.abspath(path).startswith(("/proc/", "/dev/fd/")):
            return True
        if not os.path.islink(path):
            return False
        path = os.path.join(os.path.dirname(path), os.readlink(path))
    return False


class Output:
    """One output file: ``option`` (``--vcd``), the user's ``path``, and where to write it. A
    symbolic link is written through: the file it names is the one replaced, the link stays."""

    def __init__(self, option: str, path: str, streamed: bool):
        self.option, self.path, self.streamed = option, os.fspath(path), streamed
        device, open_fd = _special(self.path), _through_proc(self.path)
        self.fd_file = open_fd and not device     # an open descriptor on a regular file: refused
        self.special = device or open_fd
        if not self.special and os.path.islink(self.path):
            self.path = os.path.realpath(self.path)
        self.temp: str | None = None
        self.done = False

    @property
    def key(self) -> str:
        return os.path.realpath(self.path)

    def check(self) -> None:
        path, opt = self.path, self.option
        if not path:
            raise ConfigError(f"{opt}: an empty file name")
        if os.path.isdir(path):
            raise ConfigError(f"{opt} {path}: is a folder; give a file name")
        if self.fd_file:
            # an open file of a process that is a regular file (``--vcd /dev/stdout > run.vcd``):
            # opened again it would start at offset 0 (truncating a log the shell appends to,
            # overwriting what the run prints); replaced, it would lose the shell's descriptor
            raise ConfigError(f"{opt} {path}: names an open file descriptor on a regular file (a shell "
                              "redirection); give that file's name instead, or pipe the output (| cat)")
        if self.special:
            if not os.access(path, os.W_OK):
                raise ConfigError(f"{opt} {path}: cannot write there (permission denied)")
            return
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            above = folder
            while above and not os.path.exists(above):
                above = os.path.dirname(above) if os.path.dirname(above) != above else ""
            if above and not os.path.isdir(above):
                raise ConfigError(f"{opt} {path}: {above} is a file, not a folder")
            raise ConfigError(f"{opt} {path}: no folder {folder}")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ConfigError(f"{opt} {path}: cannot write in folder {folder} (permission denied)")
        if os.path.exists(path) and not os.access(path, os.W_OK):
            raise ConfigError(f"{opt} {path}: the file exists and cannot be replaced (permission denied)")
        self.temp = self._temp_name()
        try:               # the surest check: make the file we will write now, before the run
            with open(self.temp, "w" if self.streamed else "x"):
                pass
        except OSError as exc:
            self.temp = None
            raise ConfigError(f"{opt} {path}: cannot write: {exc.strerror or exc}") from None

    def _temp_name(self) -> str:
        if self.streamed:
            return self.path + ".part"
        folder, base = os.path.split(os.path.abspath(self.path))
        ext = os.path.splitext(base)[1]
        return os.path.join(folder, f".{base}.{secrets.token_hex(4)}.tmp{ext}")

    @property
    def target(self) -> str:
        """The name to open for writing now."""
        return self.path if self.temp is None else self.temp

    def commit(self) -> None:
        """The file is complete: give it its name."""
        if self.temp is not None and not self.done:
            os.replace(self.temp, self.path)
        self.done = True

    def abandon(self) -> str | None:
        """The run did not complete: drop a file written at the end; a streamed one stays as
        ``<name>.part`` (returned) with a line saying it is incomplete where the format allows."""
        if self.temp is None or self.done:
            return None
        self.done = True
        if self.streamed and os.path.exists(self.temp) and os.path.getsize(self.temp) > 0:
            return self.temp
        try:
            os.remove(self.temp)
        except OSError:
            pass
        return None


class Outputs:
    """The outputs of one command, checked together before the run."""

    def __init__(self, inputs=()):
        self.items: list[Output] = []
        self.inputs = [os.path.realpath(p) for p in inputs if p and os.path.exists(p)]

    def add(self, option: str, path, streamed: bool = False) -> Output:
        out = Output(option, path, streamed)
        self.items.append(out)
        return out

    def check(self) -> None:
        """Everything a run's outputs need, before the run: ConfigError naming the first problem.
        Temporary files made by the check are removed if a later output is refused."""
        seen: dict[str, Output] = {}
        for out in self.items:
            if not out.path:
                raise ConfigError(f"{out.option}: an empty file name")
            if out.special:
                continue
            other = seen.get(out.key)
            if other is not None:
                raise ConfigError(f"{other.option} and {out.option} name the same file {out.path}; "
                                  "give each output its own name")
            if out.key in self.inputs:
                raise ConfigError(f"{out.option} {out.path}: that is an input of this run; it would be overwritten")
            seen[out.key] = out
        try:
            for out in self.items:
                out.check()
        except ConfigError:
            self.abandon()
            raise

    def commit(self) -> None:
        for out in self.items:
            out.commit()

    def commit_streamed(self) -> None:
        """The run completed: the files streamed during it are whole, whatever happens to the
        ones written after it."""
        for out in self.items:
            if out.streamed:
                out.commit()

    def get(self, option: str) -> Output | None:
        return next((out for out in self.items if out.option == option), None)

    def abandon(self) -> list[str]:
        """Drop or mark what is not complete; returns the partial files left (``.part``)."""
        return [p for p in (out.abandon() for out in self.items) if p]


def check_plot(path: str) -> None:
    """``--plot``: a format matplotlib writes, and matplotlib installed."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in PLOT_FORMATS:
        raise ConfigError(f"--plot {path}: the file name must end in .png, .pdf, .svg or .jpg")
    import importlib.util
    try:
        found = importlib.util.find_spec("matplotlib") is not None
    except (ImportError, ValueError):     # blocked or broken
        found = False
    if not found:
        raise ConfigError("--plot needs matplotlib, which is not installed: "
                          "pip install 'mcusim[plot]' (or pip install matplotlib)")
