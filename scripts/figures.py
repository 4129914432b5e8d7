#!/usr/bin/env python3
"""Measures every figure of docs/estimators.md and docs/performance.md again.

Builds the release `ickon` (or takes `--ickon PATH`), runs each section's
commands with fixed seeds, reads their `--json` output and writes each
section as generated markdown, docs/figures/SECTION.md, headed by the
machine it ran on (date, commit, CPU, cores, memory, load average at the
start, rustc, build profile). The section's region of its page, between
`<!-- figures:SECTION -->` and `<!-- /figures:SECTION -->`, is replaced
by the same tables, so that the page and the file always agree.

`--quick` runs every section small (one seed, a tour, a few seconds) to
check that the commands and their parsing still work: its output goes to
a temporary directory (or `--out`) and never into the docs.

Python 3 standard library only. See docs/performance.md for how long a
full run takes.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

sys.dont_write_bytecode = True

from figures_lib import bench, devices, estimators, performance  # noqa: E402
from figures_lib.output import header, machine, replace_region, write_whole  # noqa: E402
from figures_lib.run import FiguresError, Runner  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Section -> (page, title, function), in the order a full run goes.
SECTIONS = {}
for module, page in [
    (estimators, "estimators.md"),
    (performance, "performance.md"),
    (devices, "performance.md"),
    (bench, "performance.md"),
]:
    for name, (title, function) in module.SECTIONS.items():
        SECTIONS[name] = (page, title, function)


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Measure the figures of docs/estimators.md and docs/performance.md again.",
        epilog="Sections: " + ", ".join(SECTIONS),
    )
    p.add_argument("--ickon", help="the ickon binary to measure (default: build the release one)")
    p.add_argument("--only", help="comma-separated sections to run (default: all)")
    p.add_argument("--quick", action="store_true", help="smoke run: small sizes, output not for the docs")
    p.add_argument("--out", help="directory of the generated files (default: docs/figures; with --quick a new temporary one)")
    p.add_argument("--data", default=os.environ.get("ICKON_DATA"), help="real data directory (default: $ICKON_DATA)")
    p.add_argument("--list", action="store_true", help="list the sections and their pages, and stop")
    args = p.parse_args(argv)
    names = list(SECTIONS) if not args.only else [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [n for n in names if n not in SECTIONS]
    if unknown:
        p.error(f"unknown section(s) {', '.join(unknown)}; known: {', '.join(SECTIONS)}")
    args.sections = names
    return args


def build_release():
    """Builds the release `ickon`; returns its path."""
    print("figures: building the release ickon (cargo build --release -p ickon)", file=sys.stderr, flush=True)
    done = subprocess.run(["cargo", "build", "--release", "-p", "ickon"], cwd=REPO, check=False)
    if done.returncode != 0:
        raise FiguresError("cargo build --release -p ickon failed")
    target = os.environ.get("CARGO_TARGET_DIR") or os.path.join(REPO, "target")
    return os.path.join(target, "release", "ickon")


def profile_of(path, built):
    """The build profile, as far as the binary's path tells."""
    if built:
        return "release (built by the script)"
    parts = os.path.abspath(path).split(os.sep)
    for profile in ("release", "debug"):
        if profile in parts:
            return profile
    return f"unknown ({path})"


def update_page(page, section, body):
    """Puts `body` into the section's region of `page`; False when it has none."""
    path = os.path.join(REPO, "docs", page)
    with open(path, encoding="utf-8") as f:
        text = f.read()
    new = replace_region(text, section, body)
    if new is None:
        return False
    if new != text:
        write_whole(path, new)
    return True


def run_section(runner, name, args, out):
    """Runs one section and writes its file (and its page's region)."""
    page, title, function = SECTIONS[name]
    runner.section = name
    started = time.monotonic()
    facts = machine(REPO, runner.ickon, runner.profile)
    try:
        body = function(runner).strip()
    except (KeyError, TypeError, IndexError, ValueError) as e:
        # A report the section cannot read: its JSON changed shape.
        raise FiguresError(
            f"section {name} cannot read the report of `{runner.last_command}` "
            f"({type(e).__name__}: {e}): did its JSON change?"
        ) from e
    write_whole(os.path.join(out, f"{name}.md"), header(title, name, facts, args.quick) + "\n" + body + "\n")
    note = f"{time.monotonic() - started:.0f} s"
    if not args.quick:
        region = body + (
            f"\n\nMeasured by `scripts/figures.py --only {name}`; the machine, build and "
            f"commit are in [figures/{name}.md](figures/{name}.md)."
        )
        if not update_page(page, name, region):
            note += f"; docs/{page} has no region for it"
    runner.progress(f"written {os.path.join(out, name + '.md')} ({note})")


def _interrupted(signum, _frame):
    # As Ctrl-C: the command running is killed and waited for.
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv):
    signal.signal(signal.SIGTERM, _interrupted)
    args = parse_args(argv)
    if args.list:
        for name, (page, title, _) in SECTIONS.items():
            print(f"{name:12} docs/{page:15} {title}")
        return 0
    out = args.out or (
        tempfile.mkdtemp(prefix="ickon-figures-quick-") if args.quick else os.path.join(REPO, "docs", "figures")
    )
    try:
        ickon = os.path.abspath(args.ickon) if args.ickon else build_release()
        if not os.access(ickon, os.X_OK):
            raise FiguresError(f"no executable ickon at {ickon}")
        runner = Runner(ickon, args.quick, args.data, REPO)
        runner.profile = profile_of(ickon, not args.ickon)
        for name in args.sections:
            run_section(runner, name, args, out)
    except FiguresError as e:
        print(f"figures: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("figures: interrupted; the sections finished so far are written", file=sys.stderr)
        return 130
    print(f"figures: {len(args.sections)} section(s) written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
