"""One writer per run directory, and no process of a run left behind when it is killed.

:class:`RunLock` holds ``DIR/.rbbench.lock`` with ``flock`` for the whole run (the kernel
releases it when the run's processes are gone, so a killed run leaves no stale lock to
clean); the file holds the writer's pid, host and start time for the error message a
second writer gets (:class:`RunLockedError`).

:class:`Watchdog` is a small process forked at the start of a run, in its own process
group: when the run's process dies without stopping it (SIGKILL, a crash), it kills the
process groups registered with it (the snapshot preparation and its pool workers, which
run in their own session) and marks the manifest ``interrupted``.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import time
from datetime import datetime, timezone
from pathlib import Path

from rbbench.bench import json_text

__all__ = ["LOCK_NAME", "RunLock", "RunLockedError", "Watchdog", "mark_interrupted"]

LOCK_NAME = ".rbbench.lock"


class RunLockedError(ValueError):
    """Another run writes to the same run directory (the message names it and its pid)."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        return True
    return True


class RunLock:
    """``flock`` on ``DIR/.rbbench.lock`` for one run (a context manager).

    Parameters
    ----------
    out_dir : Path
        The run directory (created before).
    """

    def __init__(self, out_dir: Path) -> None:
        self.path = Path(out_dir) / LOCK_NAME
        self.fd: int | None = None
        self.previous: dict = {}

    def acquire(self) -> RunLock:
        """Take the lock, or raise :class:`RunLockedError` naming the holder."""
        import fcntl

        try:  # never through a symbolic link: it could truncate a file outside the run
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            if self.path.is_symlink():
                raise RunLockedError(f"{self.path}: the lock file is a symbolic link; rbbench "
                                     "does not write through links in a run directory "
                                     "(remove it)") from None
            raise RunLockedError(f"{self.path}: cannot open the lock file ({exc.strerror})"
                                 ) from None
        deadline = time.monotonic() + 10.0
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                holder = self._read(fd)
                pid = holder.get("pid")
                # a killed run's processes are ending (its watchdog cleans up): wait a little
                if (isinstance(pid, int) and not _pid_alive(pid)
                        and time.monotonic() < deadline):
                    time.sleep(0.1)
                    continue
            os.close(fd)
            pid = holder.get("pid")
            who = (f"pid {pid} on {holder.get('host')}, started {holder.get('started_at')}"
                   if pid else "a process that is starting")
            state = ("" if not isinstance(pid, int) or _pid_alive(pid)
                     else "; that process has ended, but processes it started still run")
            raise RunLockedError(
                f"{self.path.parent}: another rbbench run writes to this directory ({who}"
                f"{state}; lock file {self.path}); wait for it to end or give another --out"
            ) from None
        self.previous = self._read(fd)
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started_at": datetime.now(timezone.utc).isoformat(timespec="seconds")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        self.fd = fd
        return self

    @staticmethod
    def _read(fd: int) -> dict:
        with contextlib.suppress(OSError, ValueError):
            data = json_text.loads(os.pread(fd, 4096, 0).decode() or "{}")
            return data if isinstance(data, dict) else {}
        return {}

    def release(self) -> None:
        """Give the lock up (the file stays, empty: a later run takes it)."""
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, 0)
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def mark_interrupted(out_dir: Path, why: str) -> None:
    """Set ``state = "interrupted"`` in ``DIR/manifest.json`` if it says ``running``."""
    path = Path(out_dir) / "manifest.json"
    try:
        man = json_text.loads(json_text.read_text(path))
    except (OSError, ValueError):
        return
    if not isinstance(man, dict) or man.get("state") != "running":
        return
    man.update(state="interrupted", interrupted_by=why)
    tmp = path.with_name(f".manifest.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(man, indent=2) + "\n")
    os.replace(tmp, path)


def _watch(parent: int, fd: int, out_dir: Path) -> None:
    """The watchdog's loop: follow the registered process groups until told to quit or
    until ``parent`` dies (then kill them and mark the manifest)."""
    groups: set[int] = set()
    buf = b""
    while True:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            chunk = os.read(fd, 4096)
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                if line == b"q":
                    return
                (groups.add if line[:1] == b"+" else groups.discard)(int(line[1:]))
        if os.getppid() != parent:
            for g in groups:
                for kill in (os.killpg, os.kill):
                    with contextlib.suppress(OSError):
                        kill(g, signal.SIGKILL)
            mark_interrupted(out_dir, "the run's process died (killed) before it ended")
            return
        if ready and not chunk:  # the pipe closed: only the parent's death is left to watch
            time.sleep(0.2)


class Watchdog:
    """A forked process that cleans up after a run killed without warning (POSIX).

    :meth:`protect` / :meth:`forget` register the process groups to kill if the run
    dies; :meth:`stop` ends the watchdog when the run ends normally.
    """

    def __init__(self, out_dir: Path) -> None:
        self.pid = 0
        self.fd = -1
        if not hasattr(os, "fork"):  # pragma: no cover - not POSIX: no watchdog
            return
        r, w = os.pipe()
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:  # the watchdog: never returns
            code = 0
            try:
                os.close(w)
                os.setpgid(0, 0)  # a kill of the run's process group spares it
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                signal.signal(signal.SIGTERM, signal.SIG_IGN)
                _watch(parent, r, Path(out_dir))
            except BaseException:  # noqa: BLE001 - never return into the run's code
                code = 1
            finally:
                os._exit(code)
        os.close(r)
        self.pid, self.fd = pid, w

    def _send(self, text: str) -> None:
        if self.fd >= 0:
            with contextlib.suppress(OSError):
                os.write(self.fd, text.encode())

    def protect(self, pgid: int) -> None:
        """Kill the process group ``pgid`` (and the process ``pgid``) if the run dies."""
        self._send(f"+{pgid}\n")

    def forget(self, pgid: int) -> None:
        """The group ``pgid`` ended: nothing to kill any more."""
        self._send(f"-{pgid}\n")

    def stop(self) -> None:
        """End the watchdog (the run ended normally, or by an exception it handles)."""
        if self.fd >= 0:
            self._send("q\n")
            os.close(self.fd)
            self.fd = -1
            with contextlib.suppress(ChildProcessError):
                os.waitpid(self.pid, 0)
