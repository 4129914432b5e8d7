"""The sections of docs/performance.md measured with `ickon`: what a run
costs in virtual time, and how the live mesh holds up on one machine.

Live figures (real time, many processes) move from run to run and with
the machine's load: run these on a quiet machine and a release build.
"""

import os
import tempfile

from figures_lib import live
from figures_lib.output import fmt, mean, median, span, table, command_block


def _sim(run, args, commands):
    """`ickon sim ARGS --json`, its command line kept for the page."""
    commands.append("ickon sim " + " ".join(args))
    doc, _ = run.ickon_json(["sim"] + args + ["--json"])
    return doc


def eval_cost(run):
    """Wall and CPU time of `ickon eval` runs."""
    runs = [
        ["eval"],
        ["eval", "--estimator", "tdoa-ekf", "--route", "route-1"],
        ["eval", "--site", "warehouse", "--robots", "16", "--duration", "30"],
    ]
    if run.quick:
        runs = [["eval", "--estimator", "tdoa-ekf", "--route", "route-1", "--tours", "1"]]
    rows = []
    for args in runs:
        _, usage = run.ickon_json(args + ["--json"])
        rows.append([f"`ickon {' '.join(args)}`", fmt(usage.wall_s, 1, "s"), fmt(usage.cpu_s, 1, "s")])
    note = "Route runs use one thread per route; fleet runs one thread."
    return table(["command", "wall", "CPU"], rows) + "\n\n" + note


def latency(run):
    """Pose latency of three robots on `lab`, without and with ROS 2."""
    duration = "5" if run.quick else "90"
    variants = [("direct", [])] if run.quick else [("direct", []), ("`--ros2`", ["--ros2"])]
    rows, commands = [], []
    for name, extra in variants:
        doc = _sim(run, ["--robots", "3", "--duration", duration, "--seed", "1"] + extra, commands)
        hop = f"{fmt(_ms(doc.get('zenoh_hop_p50_us')), 2)} / {fmt(_ms(doc.get('zenoh_hop_p99_us')), 2)} ms"
        for r in live.robots(doc):
            rows.append(
                [
                    name,
                    r["id"],
                    fmt(_ms(r.get("latency_p50_us")), 2, "ms"),
                    fmt(_ms(r.get("latency_p99_us")), 2, "ms"),
                    hop,
                ]
            )
    headers = ["run", "robot", "pose latency p50", "p99", "one-hop Zenoh p50 / p99"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def _ms(us):
    return us / 1e3 if us is not None else None


def split_cores(run):
    """The site's servers on one CPU, the simulated fleet on the other."""
    sizes, duration = (["4"], "5") if run.quick else (["4", "64", "128", "256"], "30")
    rows, commands = [], []
    for n in sizes:
        doc = _sim(run, ["--site", "warehouse", "--robots", n, "--duration", duration, "--split-cores"], commands)
        rows.append(
            [
                n,
                fmt(doc["cycles_per_s"], 1),
                fmt(live.fired_worst(doc), 0, "%"),
                fmt(live.sync_max_us(doc), 0, "µs"),
                live.share_pair(doc),
                fmt(live.mean_error_mm(doc), 1, "mm"),
                live.latency_pair(doc),
                fmt(live.cost_cores(doc, "servers"), 2, "cores"),
                fmt(live.cost_cores(doc, "simulation"), 2, "cores"),
            ]
        )
    headers = ["robots", "cycles/s", "cells firing when due, worst", "cells' sync error max"]
    headers += ["fix share, worst / mean", "mean error", "pose latency p50 / p99"]
    headers += ["servers (first CPUs)", "simulation (the others)"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def grouping(run):
    """Robots per process at 64 robots, the servers on their own CPUs."""
    robots, groups, duration = ("4", ["1", "4"], "5") if run.quick else ("64", ["1", "4", "16", "64"], "20")
    rows, commands = [], []
    for k in groups:
        args = ["--site", "warehouse", "--robots", robots, "--duration", duration]
        doc = _sim(run, args + ["--split-cores", "--robots-per-process", k], commands)
        cpu, mib = live.agent(doc)
        rows.append(
            [
                k,
                fmt(live.cost_cores(doc, "simulation"), 2, "cores"),
                fmt(live.sync_max_us(doc), 0, "µs"),
                fmt(live.fix_share(doc)[0], 1, "%"),
                live.latency_pair(doc),
                f"{fmt(cpu, 1)} ms/s, {fmt(mib, 1)} MiB",
            ]
        )
    headers = ["robots per process", "simulation CPU", "cells' sync error max", "fix share, worst"]
    headers += ["pose latency p50 / p99", "one robot's agent"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def one_robot(run):
    """What one robot's agent needs, in a process of its own."""
    runs = [("lab", "3", "30"), ("warehouse", "64", "20")]
    if run.quick:
        runs = [("lab", "3", "5")]
    rows, commands = [], []
    for site, robots, duration in runs:
        args = ["--site", site, "--robots", robots, "--robots-per-process", "1", "--duration", duration]
        doc = _sim(run, args, commands)
        cpu, mib = live.agent(doc)
        share = f" ({cpu / 10:.1f} % of a core)" if cpu is not None else ""
        rows.append(
            [
                f"`{site}` ({robots} robots, {duration} s)",
                fmt(doc["cycles_per_s"], 1),
                fmt(cpu, 1, "ms") + share,
                fmt(mib, 1, "MiB"),
            ]
        )
    headers = ["site", "cycles/s", "CPU per second of driving", "peak memory"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def _zone_row(site, routers, doc):
    loads = doc.get("routers", [])
    cpu = ", ".join(f"{r['zone']}{' (hub)' if r.get('hub') and len(loads) > 1 else ''} {fmt(r.get('cpu_s'), 1)} s" for r in loads)
    mib = span([r.get("peak_rss_mib") for r in loads], 0, "MiB")
    p50, p99 = live.latency_ms(doc)
    return [
        f"`{site}`",
        routers,
        fmt(live.fixes_per_s(doc), 2),
        fmt(live.fix_share(doc)[1], 1, "%"),
        fmt(live.fired_worst(doc), 1, "%"),
        fmt(p50, 1, "ms"),
        fmt(p99, 1, "ms"),
        fmt(live.sync_max_us(doc), 0, "µs"),
        cpu,
        mib,
    ]


def zones(run):
    """One router against one per zone, runs of the two layouts interleaved."""
    if run.quick:
        plan = [("lab", "3", ["1", "2"], 1, "5")]
    else:
        plan = [("lab", "5", ["1", "2"], 3, "30"), ("warehouse", "16", ["1", "4"], 1, "30")]
    rows, commands = [], []
    for site, robots, layouts, repeats, duration in plan:
        for _ in range(repeats):
            for routers in layouts:
                args = ["--site", site, "--robots", robots, "--routers", routers]
                doc = _sim(run, args + ["--seed", "1", "--duration", duration], commands)
                rows.append(_zone_row(site, routers, doc))
    headers = ["site", "routers", "fixes/s per robot", "fix share, mean", "cells fired, worst"]
    headers += ["pose latency p50", "p99, worst robot", "sync error max", "CPU per router", "peak memory per router"]
    return command_block(_unique(commands)) + "\n\n" + table(headers, rows)


def _unique(commands):
    seen = []
    for c in commands:
        if c not in seen:
            seen.append(c)
    return seen


def _scale_rows(results):
    rows = []
    for size in results:
        doc = size["report"]
        rows.append(
            [
                str(size["robots"]) + (" (failed)" if size.get("failure") else ""),
                fmt(doc["cycles_per_s"], 1),
                fmt(live.fired_worst(doc), 0, "%"),
                fmt(live.fix_share(doc)[0], 1, "%"),
                fmt(live.sync_max_us(doc), 0, "µs"),
                live.latency_pair(doc),
                fmt(live.mean_error_mm(doc), 0, "mm"),
            ]
        )
    return rows


def scale(run):
    """Larger fleets, every robot's agent a process of its own."""
    sizes, duration = ("4", "5") if run.quick else ("16,64", "30")
    args = ["bench", "scale", "--site", "warehouse", "--robots", sizes, "--duration", duration]
    args += ["--robots-per-process", "1"]
    results, _ = run.ickon_json(args + ["--json"])
    headers = ["robots", "cycles/s", "cells firing when due", "fix share, worst robot"]
    headers += ["cells' sync error max", "pose latency p50 / p99", "mean error"]
    return command_block(["ickon " + " ".join(args)]) + "\n\n" + table(headers, _scale_rows(results))


def access(run):
    """The router's access control against none, each fleet size."""
    sizes, duration = ("4", "5") if run.quick else ("16,64", "30")
    base = ["bench", "scale", "--site", "warehouse", "--robots", sizes, "--duration", duration]
    rows, commands = [], []
    for name, extra in [("none", []), ("`--secure`", ["--secure"])]:
        commands.append("ickon " + " ".join(base + extra))
        results, _ = run.ickon_json(base + extra + ["--json"])
        for size in results:
            doc = size["report"]
            rows.append(
                [
                    str(size["robots"]),
                    name,
                    fmt(live.process_cpu_s(doc, "router"), 1, "s"),
                    fmt(live.process_peak_mib(doc, "router"), 1, "MiB"),
                    fmt(live.process_cpu_s(doc), 1, "s"),
                    fmt(live.fix_share(doc)[1], 1, "%"),
                ]
            )
    rows.sort(key=lambda r: int(r[0]))
    headers = ["robots", "access control", "router CPU", "router peak memory", "CPU, all processes", "fix share, mean"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def tls(run):
    """Mutual TLS against the same access control with links in clear."""
    robots, duration, repeats = ("2", "5", 1) if run.quick else ("5", "30", 3)
    with tempfile.TemporaryDirectory(prefix="ickon-figures-tls-") as tmp:
        plain = os.path.join(tmp, "plain")
        secure = ["site", "secure", "--sim", "--out", plain]
        secure += ["--listen", "tcp/127.0.0.1:7447", "--connect", "tcp/127.0.0.1:7447"]
        run.command([run.ickon] + secure)
        commands = ["ickon " + " ".join(secure).replace(plain, "plain")]
        runs = {"mutual TLS": [], "TCP, passwords only": []}
        for _ in range(repeats):
            for name, extra in [("TCP, passwords only", ["--secure", plain]), ("mutual TLS", ["--secure"])]:
                args = ["--robots", robots, "--duration", duration, "--seed", "7"] + extra
                runs[name].append(_sim(run, args, commands))
    rows = [_tls_row(name, docs) for name, docs in runs.items()]
    headers = ["links", f"CPU, all processes ({repeats} run{'s' if repeats > 1 else ''})", "mean", "router", "pose latency p50 / p99", "fixes"]
    note = (
        "CPU is the sum over every process of a run; the latency is the median over the "
        "robots of each robot's p50 and p99, averaged over the runs; fixes are the "
        "robots' fixes of a run, averaged. The two kinds of run alternate."
    )
    commands = [c.replace(plain, "plain") for c in _unique(commands)]
    return command_block(commands) + "\n\n" + table(headers, rows) + "\n\n" + note


def _robots_median_ms(doc, key):
    value = median(r.get(key) for r in live.robots(doc))
    return value / 1e3 if value is not None else None


def _tls_row(name, docs):
    cpu = [live.process_cpu_s(d) for d in docs]
    p50 = mean(_robots_median_ms(d, "latency_p50_us") for d in docs)
    p99 = mean(_robots_median_ms(d, "latency_p99_us") for d in docs)
    fixes = mean(sum(r.get("fixes", 0) for r in live.robots(d)) for d in docs)
    return [
        name,
        ", ".join(fmt(c, 1) for c in cpu) + " s",
        fmt(mean(cpu), 1, "s"),
        fmt(mean(live.process_cpu_s(d, "router") for d in docs), 2, "s"),
        f"{fmt(p50, 1)} / {fmt(p99, 1)} ms",
        fmt(fixes, 0),
    ]


SECTIONS = {
    "eval-cost": ("What `ickon eval` costs", eval_cost),
    "latency": ("Pose latency on `lab`", latency),
    "split-cores": ("The site's servers apart from the fleet", split_cores),
    "grouping": ("Robots per process", grouping),
    "one-robot": ("What one robot needs", one_robot),
    "zones": ("Zones on several routers", zones),
    "scale": ("Larger fleets, an agent per process", scale),
    "access": ("Access control on the router", access),
    "tls": ("Mutual TLS", tls),
}
