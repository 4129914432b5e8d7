"""Running `ickon` for the figures: one command at a time, its JSON parsed,
its wall and CPU time measured, a clear error when it fails.

Every command runs with a private XDG_RUNTIME_DIR, so that a run's file
(`ickon sim` writes one for `ickon admin`) never meets another site's
running on the same machine.
"""

import json
import os
import resource
import shlex
import subprocess
import sys
import tempfile
import time


class FiguresError(Exception):
    """A command failed or printed what the script cannot read."""


class Usage:
    """What one command cost: wall seconds and CPU seconds of its processes."""

    def __init__(self, wall_s, cpu_s):
        self.wall_s = wall_s
        self.cpu_s = cpu_s


def _children_cpu_s():
    """CPU seconds (user and system) of every waited-for child so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


class Runner:
    """Runs the commands of the figures and tells the user what it does.

    `ickon` is the binary's path, `quick` asks for the smoke run's sizes,
    `data` is the real-data directory (ICKON_DATA) or None, `repo` the
    repository's root (for `cargo bench`).
    """

    def __init__(self, ickon, quick, data, repo):
        self.ickon = ickon
        self.quick = quick
        self.data = data
        self.repo = repo
        self.section = ""
        self.commands = 0
        self.profile = "unknown"
        self.last_command = ""

    def progress(self, text):
        """One progress line on stderr (stdout stays for the summary)."""
        print(f"figures [{self.section}] {text}", file=sys.stderr, flush=True)

    def need_data(self, sub):
        """The real-data directory `sub` under ICKON_DATA, or a clear error."""
        if not self.data:
            raise FiguresError(
                f"section {self.section} replays real data: set ICKON_DATA "
                "(or --data) to the directory holding util/, util-imu/ and plaza/"
            )
        path = os.path.join(self.data, sub)
        if not os.path.isdir(path):
            raise FiguresError(f"section {self.section}: no directory {path}")
        return path

    def command(self, argv, env=None, cwd=None):
        """Runs `argv`; returns (stdout, stderr, Usage). Fails on a non-zero exit."""
        self.commands += 1
        shown = " ".join(shlex.quote(a) for a in argv)
        self.last_command = shown
        self.progress(f"$ {shown}")
        full_env = dict(os.environ)
        full_env.update(env or {})
        with tempfile.TemporaryDirectory(prefix="ickon-figures-") as runtime:
            full_env["XDG_RUNTIME_DIR"] = runtime
            cpu0, wall0 = _children_cpu_s(), time.monotonic()
            try:
                done = subprocess.run(
                    argv,
                    env=full_env,
                    cwd=cwd or runtime,
                    stdin=subprocess.DEVNULL,
                    capture_output=True,
                    text=True,
                    check=False,
                )
            except OSError as e:
                raise FiguresError(f"cannot run `{shown}`: {e}") from e
            usage = Usage(time.monotonic() - wall0, _children_cpu_s() - cpu0)
        if done.returncode != 0:
            tail = "\n".join(done.stderr.strip().splitlines()[-20:])
            raise FiguresError(
                f"`{shown}` exited with status {done.returncode}; its last lines:\n{tail}"
            )
        self.progress(f"  done in {usage.wall_s:.1f} s wall, {usage.cpu_s:.1f} s CPU")
        return done.stdout, done.stderr, usage

    def ickon_json(self, args, env=None):
        """Runs `ickon ARGS` (with `--json` in ARGS); returns (document, Usage)."""
        out, _, usage = self.command([self.ickon] + list(args), env=env)
        return parse_json(out, "ickon " + " ".join(args)), usage


def parse_json(text, what):
    """The last JSON document of `text` (a command may log lines before it)."""
    text = text.strip()
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        pass
    for opener in ("\n{", "\n["):
        at = text.rfind(opener)
        if at >= 0:
            try:
                return json.loads(text[at + 1 :])
            except json.JSONDecodeError:
                continue
    raise FiguresError(f"`{what}` printed no JSON document; it printed:\n{text[-2000:]}")
