"""The sections of docs/performance.md on devices: the live mesh direct,
through emulated boards, and on an emulated Marvelmind kit, each robot's
accuracy and latency (`ickon sim --devices`, `--receivers`).
"""

from figures_lib.output import fmt, mean, span, table, command_block


def _runs(run, args, seeds, commands, fired=None):
    """Every robot of `ickon sim ARGS --seed N` for each seed; the
    transmitters each run's cycles fired go into `fired`."""
    robots = []
    for seed in seeds:
        full = args + ["--seed", str(seed)]
        commands.append("ickon sim " + " ".join(full))
        doc, _ = run.ickon_json(["sim"] + full + ["--json"])
        robots += doc["robots"]
        if fired is not None and doc.get("firing_plan"):
            fired.append(doc["firing_plan"]["transmitters_per_cycle"])
    return robots


def _range_mean(robots, key, digits, scale=1.0):
    values = [r[key] * scale for r in robots if r.get(key) is not None]
    return f"{span(values, digits)} ({fmt(mean(values), digits)})"


def devices(run):
    """Two robots on `lab`, direct and through emulated boards, seeds 1-3."""
    seeds, duration = ([1], "5") if run.quick else ([1, 2, 3], "30")
    rows, commands = [], []
    for name, extra in [("direct", []), ("through boards", ["--devices", "emulated"])]:
        fired = []
        robots = _runs(run, ["--robots", "2", "--duration", duration] + extra, seeds, commands, fired)
        rows.append(
            [
                name,
                _range_mean(robots, "mean_mm", 1),
                span([r.get("p95_mm") for r in robots], 1),
                _range_mean(robots, "fixes_per_s", 2),
                span([r.get("fix_share") for r in robots], 2),
                span(fired, 1),
                span([r["latency_p50_us"] / 1e3 for r in robots if r.get("latency_p50_us")], 2),
                span([r["latency_p99_us"] / 1e3 for r in robots if r.get("latency_p99_us")], 1),
            ]
        )
    headers = ["run", "mean error mm (mean)", "p95 mm", "fixes/s (mean)", "fixes per cycle", "transmitters a cycle"]
    headers += ["pose latency p50 ms", "p99 ms"]
    return command_block(commands) + "\n\n" + table(headers, rows)


def _kit_rows(label, robots):
    return [
        [label, "the agent (`tdoa-ekf`, distances and wheels)", span([r.get("mean_mm") for r in robots], 1),
         span([r.get("p95_mm") for r in robots], 1), span([r.get("scored_poses") for r in robots], 0)],
        ["", "the kit's own positions", span([r.get("kit_mean_mm") for r in robots], 1),
         span([r.get("kit_p95_mm") for r in robots], 1), span([r.get("kit_positions") for r in robots], 0)],
    ]


def kits(run):
    """Robots on an emulated Marvelmind kit: the agent against the kit's own positions."""
    seeds, duration = ([1], "5") if run.quick else ([1, 2, 3], "30")
    commands = []
    lab = _runs(run, ["--robots", "2", "--duration", duration, "--receivers", "marvelmind"], seeds, commands)
    rows = _kit_rows(f"`lab`, {len(lab)} robots", lab)
    if not run.quick:
        site = f"{run.repo}/deploy/sites/marvelmind-warehouse.toml"
        args = ["--site", site, "--robots", "4", "--duration", "30", "--receivers", "marvelmind"]
        wh = _runs(run, args, [1, 2], commands)
        rows += _kit_rows(f"`marvelmind-warehouse`, {len(wh)} robots", wh)
    commands = [c.replace(run.repo + "/", "") for c in commands]
    headers = ["site", "track", "mean error mm", "p95 mm", "positions scored per robot"]
    return command_block(commands) + "\n\n" + table(headers, rows)


SECTIONS = {
    "devices": ("Devices: direct and through emulated boards", devices),
    "kits": ("Marvelmind kits", kits),
}
