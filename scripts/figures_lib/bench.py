"""The sections of docs/performance.md that are benchmarks: one central unit
against a synthetic fleet (`ickon bench central`), the recorder's writer
(`ickon record --synthetic-robots`) and the Criterion benchmarks of the
fix solver and the firing plan (`cargo bench`, read from Criterion's
`estimates.json`).
"""

import json
import os
import re
import tempfile

from figures_lib.output import fmt, table, command_block
from figures_lib.run import FiguresError


def _ms(us):
    return us / 1e3 if us is not None else None


def _central_row(r):
    if r.get("failure"):
        return [f"{r['robots']:,}", r["failure"]] + ["-"] * 8
    admin = (
        f"{fmt(r.get('admin_status_p50_ms'), 1)} / {fmt(r.get('admin_status_p99_ms'), 0)} ms, "
        f"{r['admin_status_unanswered']} of {r['admin_status_asked']}"
    )
    return [
        f"{r['robots']:,}",
        fmt(r.get("live_s"), 1, "s"),
        fmt((r.get("central_cpu_share") or 0) * 100 if r.get("central_cpu_share") is not None else None, 0, "%"),
        fmt(r.get("central_peak_rss_mib"), 0, "MiB"),
        str(r["cycles"]),
        f"{fmt(_ms(r.get('trigger_jitter_p50_us')), 1)} / {fmt(_ms(r.get('trigger_jitter_p99_us')), 1)} ms",
        admin,
        f"{fmt(r.get('web_status_p50_ms'), 1)} / {fmt(r.get('web_status_p99_ms'), 0)} ms",
        fmt(r.get("sync_error_max_us"), 0, "µs"),
        f"{r.get('robots_up_at_central', '-')} / {r.get('robots_posed_at_central', '-')}",
    ]


def central(run):
    """The central unit alone on CPU 0 against a synthetic fleet, then zones."""
    if run.quick:
        plans = [("50", "5", "1"), ("50", "5", "2")]
    else:
        plans = [("300,1000,3000,10000", "20", "1"), ("1000", "30", "4")]
    rows, commands = [], []
    for sizes, duration, routers in plans:
        args = ["bench", "central", "--robots", sizes, "--duration", duration]
        args += ["--routers", routers] if routers != "1" else []
        commands.append("ickon " + " ".join(args))
        reports, _ = run.ickon_json(args + ["--json"])
        rows += [[routers, duration + " s"] + _central_row(r) for r in reports]
    headers = ["routers", "run", "robots", "live", "central CPU (one core)", "peak memory", "cycles"]
    headers += ["trigger jitter p50 / p99", "`admin status` p50 / p99, unanswered", "web p50 / p99"]
    headers += ["cells' sync max", "up / posed"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def record(run):
    """The recorder's writer against the message mix of a simulated fleet."""
    robots, duration = ("2", "2") if run.quick else ("64", "60")
    with tempfile.TemporaryDirectory(prefix="ickon-figures-rec-") as tmp:
        out = os.path.join(tmp, "synthetic.mcap")
        args = ["record", "--synthetic-robots", robots, "--duration", duration, "--out", out]
        doc, _ = run.ickon_json(args + ["--json"])
    site_rate = doc["messages_per_s"]
    rows = [
        [
            robots,
            fmt(site_rate, 0),
            fmt(doc["mb_per_min"], 1, "MB"),
            fmt(doc["capacity_messages_per_s"], 0),
            fmt(doc["capacity_messages_per_s"] / site_rate if site_rate else None, 1) + " times",
            fmt(doc["cpu_share_at_site_rate"] * 100, 1, "%"),
        ]
    ]
    headers = ["robots", "site's messages/s", "per minute", "recorder wrote, messages/s"]
    headers += ["of the site's rate", "one core per second of site time"]
    shown = "ickon " + " ".join(args).replace(out, "synthetic.mcap")
    return command_block([shown]) + "\n\n" + table(headers, rows)


def _cargo_bench(run, package, bench):
    """Runs one Criterion benchmark; returns (stderr, Criterion's folder)."""
    target = os.environ.get("CARGO_TARGET_DIR") or os.path.join(run.repo, "target")
    argv = ["cargo", "bench", "-p", package, "--bench", bench]
    if run.quick:
        # A smoke run: the test build's profile (no release build) and
        # Criterion's shortest measurement.
        argv += ["--profile", "dev", "--", "--quick"]
    _, err, _ = run.command(argv, cwd=run.repo)
    return err, os.path.join(target, "criterion")


def _estimate_us(folder, *parts):
    """Criterion's mean time of one benchmark, microseconds."""
    path = os.path.join(folder, *parts, "new", "estimates.json")
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)["mean"]["point_estimate"] / 1e3
    except (OSError, KeyError, ValueError) as e:
        raise FiguresError(f"no Criterion estimate at {path}: {e}") from e


def solver(run):
    """Time per fix of the TDOA solver (`cargo bench -p ickon-fusion --bench tdoa`)."""
    _, folder = _cargo_bench(run, "ickon-fusion", "tdoa")
    group = os.path.join(folder, "tdoa")

    def pair(kind, n):
        a = _estimate_us(group, f"{kind}_2d", str(n))
        b = _estimate_us(group, f"{kind}_3d", str(n))
        return f"{a:.2f} / {b:.2f} µs"

    rows = [
        ["closed form, 2D / 3D"] + [pair("closed_form", n) for n in (4, 8, 16)],
        ["full solve with refinement, 2D / 3D"] + [pair("solve_refined", n) for n in (4, 8, 16)],
    ]
    consensus = [f"{_estimate_us(group, 'solve_consensus_2d', str(n)):.1f} µs" for n in (8, 16)]
    rows.append(["consensus (a wrong id and 2 or 5 reflections), 2D", ""] + consensus)
    return (
        command_block(["cargo bench -p ickon-fusion --bench tdoa"])
        + "\n\nTime per fix (Criterion's mean):\n\n"
        + table(["", "4 signals", "8 signals", "16 signals"], rows)
    )


def firing_plan(run):
    """Time to plan one cycle for 128 robots (`cargo bench -p ickon-central --bench firing_plan`)."""
    err, folder = _cargo_bench(run, "ickon-central", "firing_plan")
    rows = []
    line = re.compile(r"^(\w+): (\d+) robots, (\d+) transmitters fire, cycle period ([\d.]+) ms$", re.M)
    seen = set()
    for site, robots, fired, period in line.findall(err):
        if site in seen:
            continue
        seen.add(site)
        plan_us = _estimate_us(folder, "firing_plan_128_robots", "plan", site)
        share = plan_us / 1e3 / float(period) * 100
        rows.append([f"`{site}`", fired, f"{period} ms", fmt(plan_us / 1e3, 1, "ms"), fmt(share, 1, "%")])
    if not rows:
        raise FiguresError("the firing plan benchmark printed no site line on stderr")
    headers = ["site", "transmitters fired", "cycle planned", "plan time", "share of the cycle"]
    return command_block(["cargo bench -p ickon-central --bench firing_plan"]) + "\n\n" + table(headers, rows)


SECTIONS = {
    "central": ("One central unit against a synthetic fleet", central),
    "record": ("Recording", record),
    "solver": ("The fix solver", solver),
    "firing-plan": ("The firing plan", firing_plan),
}
