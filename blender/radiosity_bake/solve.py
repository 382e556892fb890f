# SPDX-License-Identifier: GPL-3.0-or-later
"""Running the radiosity program on the exported scene, in the background.

The program is found in the add-on's preferences, then ``RADIOSITY_BIN``,
then ``PATH``. It solves by progressive radiosity (Wallace, Elmquist &
Haines 1989; Wong & Tsang 1993) and reports its progress as JSON events,
one a line, in a file (``--progress-json``), which :class:`Events` reads as
it grows. Stopping works on every system: the add-on creates the file named
by ``--stop-file``, and the program writes its outputs from the light
reached (as a first Ctrl-C does in a terminal); abandoning kills it, and
its outputs, written under temporary names until complete, never appear.
"""

import json
import os
import shutil
import subprocess
import time

from .prepare import BakeError

#: The environment variable naming the program, after the preferences.
ENVIRONMENT = "RADIOSITY_BIN"


def find_binary(preference=""):
    """The radiosity program: `preference`, then ``RADIOSITY_BIN``, then
    ``radiosity`` on ``PATH``."""
    tried = []
    for where, candidate in (
        ("the add-on's preferences", preference),
        (ENVIRONMENT, os.environ.get(ENVIRONMENT, "")),
    ):
        if candidate:
            path = os.path.abspath(os.path.expanduser(candidate))
            if os.path.isfile(path) and os.access(path, os.X_OK):
                return path
            tried.append(f"{where} names {candidate}, which is not an executable file")
    found = shutil.which("radiosity")
    if found:
        return found
    tried.append("no 'radiosity' on PATH")
    raise BakeError(
        "the radiosity program was not found ("
        + "; ".join(tried)
        + "): build it with 'cargo build --release' and set its path in the add-on's "
        "preferences, or in RADIOSITY_BIN"
    )


class Events:
    """The program's JSON events, read from `path` as it grows."""

    def __init__(self, path):
        self.path = path
        self.offset = 0
        self.partial = b""

    def read(self):
        """The events written since the last call (complete lines only)."""
        try:
            with open(self.path, "rb") as f:
                f.seek(self.offset)
                data = f.read()
        except FileNotFoundError:
            return []
        self.offset += len(data)
        lines = (self.partial + data).split(b"\n")
        self.partial = lines.pop()
        events = []
        for line in lines:
            line = line.strip()
            if not line:
                continue
            try:
                events.append(json.loads(line))
            except ValueError:
                continue
        return events


class Solve:
    """One run of the program: started at once, followed with :meth:`poll`."""

    def __init__(self, command, folder):
        self.command = command
        self.folder = folder
        self.events = Events(os.path.join(folder, "progress.jsonl"))
        self.stop_file = os.path.join(folder, "stop")
        self.log = os.path.join(folder, "radiosity.log")
        self.progress = None
        self.stage = "starting"
        self.done = None
        self.error = None
        self.stopping = False
        self.started = time.perf_counter()
        #: Seconds the program ran (seen ended by :meth:`poll`).
        self.seconds = None
        with open(self.log, "wb") as log:
            self.process = subprocess.Popen(
                command + ["--progress-json", self.events.path, "--stop-file", self.stop_file],
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                cwd=folder,
            )

    def poll(self):
        """Reads new events; True once the program has ended."""
        ended = self.process.poll() is not None
        if ended and self.seconds is None:
            self.seconds = time.perf_counter() - self.started
        for event in self.events.read():
            kind = event.get("event")
            if kind == "progress":
                self.progress = event
                self.stage = "solving"
            elif kind == "stage":
                self.stage = event.get("stage", self.stage)
                if kind == "stage" and event.get("message"):
                    self.stage = event["message"]
            elif kind == "final_pass":
                done, total = event.get("done", 0), event.get("total", 0)
                what = event.get("what", "")
                self.stage = (
                    f"final pass: {what} {100 * done / total:.0f}%"
                    if total
                    else f"final pass: {what}"
                )
            elif kind == "done":
                self.done = event
            elif kind == "error":
                self.error = event.get("message", "")
        return ended

    def request_stop(self):
        """Asks the program to stop and write what it has (the stop file)."""
        if not self.stopping:
            self.stopping = True
            with open(self.stop_file, "w") as f:
                f.write("stop\n")

    def abandon(self):
        """Kills the program: nothing it would have written appears."""
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()

    def status(self):
        """One line for the status bar."""
        p = self.progress
        if self.stopping:
            prefix = "Radiosity: stopping, writing the light reached (Esc again abandons)"
        elif p is None or self.stage.startswith("final pass"):
            return f"Radiosity: {self.stage}"
        else:
            prefix = "Radiosity"
        if p is None:
            return prefix
        left = p.get("remaining_s")
        left = f", about {format_seconds(left)} left" if left is not None else ""
        return (
            f"{prefix}: {p['shots']} shots, unshot {100 * (p.get('unshot_fraction') or 0):.2f}% "
            f"(stops at {100 * p['stop_at']:.2f}%){left}"
            + ("" if self.stopping else " - Esc stops with the light so far")
        )

    def completion(self):
        """Estimated completion in [0, 1]."""
        if self.progress is None:
            return 0.0
        return max(0.0, min(1.0, self.progress.get("completion") or 0.0))

    def finish(self):
        """The `done` event of a run that ended well; else the program's
        error, as a :class:`BakeError`."""
        self.poll()
        code = self.process.wait()
        if code == 0 and self.done is not None:
            return self.done
        message = self.error
        if not message:
            try:
                with open(self.log, encoding="utf-8", errors="replace") as f:
                    lines = [l.strip() for l in f if l.strip()]
                errors = [l for l in lines if l.startswith("error")]
                message = (errors or lines or [f"exit status {code}"])[-1]
            except OSError:
                message = f"exit status {code}"
        raise BakeError(f"the solve failed: {message}")


def format_seconds(seconds):
    """`1:02:03` or `2:03`."""
    s = round(seconds)
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02}:{s % 60:02}"
    return f"{s // 60}:{s % 60:02}"
