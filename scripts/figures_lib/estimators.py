"""The sections of docs/estimators.md: accuracy in virtual time (`ickon
eval`), on the live mesh (`ickon sim`) and on real data (`ickon replay`).

The simulator is deterministic: the same command and seed give the same
numbers on any machine and either build profile, so these sections need no
quiet machine (the live mesh's excepted).
"""

from figures_lib.output import fmt, mean, span, table, command_block


def _route_runs(run, seeds, extra):
    """Every (seed, estimator, route) of `ickon eval --json` over `seeds`:
    its mean error, share under 100 mm and ratio to the Cramér-Rao bound."""
    runs, channels, commands = [], [], []
    for seed in seeds:
        args = ["eval", "--estimator", "all", "--seed", str(seed)] + extra
        commands.append("ickon " + " ".join(args))
        doc, _ = run.ickon_json(args + ["--json"])
        for r in doc["results"]:
            runs.append(
                {
                    "seed": seed,
                    "estimator": r["estimator"],
                    "route": r["route"],
                    "mean_mm": r["mean"]["mean_mm"],
                    "under_100": r["mean"]["under_100"],
                    "heading_std_deg": r["mean"].get("heading_std_deg"),
                    "crlb_ratio": r.get("crlb_ratio"),
                }
            )
        channels += [c["fixes_per_s"] for c in doc.get("channel", [])]
    return runs, channels, commands


def _accuracy_table(runs):
    """One row per estimator, best first: mean over the route runs, the worst
    route run and the lowest share under 100 mm."""
    names = sorted({r["estimator"] for r in runs})
    rows = []
    for name in names:
        mine = [r for r in runs if r["estimator"] == name]
        rows.append(
            (
                mean(r["mean_mm"] for r in mine),
                [
                    f"`{name}`",
                    fmt(mean(r["mean_mm"] for r in mine), 1, "mm"),
                    fmt(max(r["mean_mm"] for r in mine), 1, "mm"),
                    fmt(min(r["under_100"] for r in mine), 1, "%"),
                    span([r["heading_std_deg"] for r in mine], 1, "deg"),
                ],
            )
        )
    rows.sort(key=lambda r: r[0])
    headers = ["estimator", "mean error", "worst route run", "lowest share under 100 mm"]
    headers += ["heading error sd, per route run"]
    return table(headers, [r[1] for r in rows])


def _ratio_line(runs):
    """How far `tdoa-ekf` stays below the others and the bound, in every run."""
    by_run = {}
    for r in runs:
        by_run.setdefault((r["seed"], r["route"]), {})[r["estimator"]] = r
    worst = {"ickon-akf": 0.0, "gyro-ckf": 0.0, "crlb": 0.0}
    for ests in by_run.values():
        ours = ests.get("tdoa-ekf")
        if ours is None:
            continue
        for other in ("ickon-akf", "gyro-ckf"):
            if other in ests and ests[other]["mean_mm"] > 0:
                ratio = ours["mean_mm"] / ests[other]["mean_mm"]
                worst[other] = max(worst[other], ratio)
        if ours["crlb_ratio"] is not None:
            worst["crlb"] = max(worst["crlb"], ours["crlb_ratio"])
    return (
        f"In every one of the {len(by_run)} route runs `tdoa-ekf`'s mean error is at most "
        f"{worst['ickon-akf']:.2f} times `ickon-akf`'s, {worst['gyro-ckf']:.2f} times "
        f"`gyro-ckf`'s and {worst['crlb']:.2f} times the Cramér-Rao bound of one raw fix "
        "(the best a single fix could do with the timing noise alone)."
    )


def lab(run):
    """`ickon eval` on `lab`, every estimator and route, seeds 1-9."""
    seeds = [1] if run.quick else range(1, 10)
    extra = ["--tours", "1", "--route", "route-1"] if run.quick else []
    runs, _, commands = _route_runs(run, seeds, extra)
    return "\n\n".join(
        [
            command_block(commands),
            f"Over the route runs of seeds {span(seeds, 0)} ({len(runs)} runs of an estimator "
            f"on a route, {1 if run.quick else 10} tours each; `paper` profile, tight schedule, "
            "survey calibration on):",
            _accuracy_table(runs),
            _ratio_line(runs),
        ]
    )


def paper(run):
    """`ickon-akf` with the ICKON paper's schedule and no calibration."""
    seeds = [1] if run.quick else [1, 2]
    rows, commands, routes = [], [], []
    for seed in seeds:
        args = ["eval", "--schedule", "uniform", "--estimator", "ickon-akf"]
        args += ["--no-survey-calibration", "--seed", str(seed)]
        args += ["--tours", "1", "--route", "route-1"] if run.quick else []
        commands.append("ickon " + " ".join(args))
        doc, _ = run.ickon_json(args + ["--json"])
        cells = {}
        for r in doc["results"]:
            if r["route"] not in routes:
                routes.append(r["route"])
            cells[r["route"]] = f"{r['mean']['mean_mm']:.1f} mm ({r['mean']['under_100']:.0f} %)"
        rows.append([str(seed)] + [cells.get(route, "-") for route in routes])
    headers = ["seed"] + [f"`{r}` mean (share under 100 mm)" for r in routes]
    return command_block(commands) + "\n\n" + table(headers, rows)


def warehouse(run):
    """`ickon eval` on `warehouse`, one robot per route, seeds 1-3."""
    seeds = [1] if run.quick else [1, 2, 3]
    extra = ["--site", "warehouse", "--tours", "1" if run.quick else "3"]
    extra += ["--route", "aisle-1"] if run.quick else []
    runs, channels, commands = _route_runs(run, seeds, extra)
    ours = [r for r in runs if r["estimator"] == "tdoa-ekf"]
    return "\n\n".join(
        [
            command_block(commands),
            _accuracy_table(runs),
            _ratio_line(runs),
            f"`tdoa-ekf`'s lowest share of points under 100 mm in a run: "
            f"{min(r['under_100'] for r in ours):.1f} %. A route run fires the whole "
            f"schedule every cycle: {span(channels, 1)} fixes per second.",
        ]
    )


def fleet(run):
    """Sixteen robots on `warehouse` at once, occupancy firing, seeds 1-4."""
    seeds = [1] if run.quick else [1, 2, 3, 4]
    robots, duration = ("4", "5") if run.quick else ("16", "30")
    rows, commands, rates = [], [], []
    for seed in seeds:
        args = ["eval", "--site", "warehouse", "--robots", robots]
        args += ["--duration", duration, "--seed", str(seed)]
        commands.append("ickon " + " ".join(args))
        doc, _ = run.ickon_json(args + ["--json"])
        errs = [r["mean_err_mm"] for r in doc["fleet"]["robots"]]
        rates += [r["fixes_per_s"] for r in doc["fleet"]["robots"]]
        rows.append(
            [
                str(seed),
                fmt(mean(errs), 1, "mm"),
                fmt(max(errs), 0, "mm"),
                fmt(mean(r["fixes_per_s"] for r in doc["fleet"]["robots"]), 1),
            ]
        )
    alone = []
    for seed in seeds:
        args = ["eval", "--site", "warehouse", "--robots", "1", "--duration", duration, "--seed", str(seed)]
        commands.append("ickon " + " ".join(args))
        doc, _ = run.ickon_json(args + ["--json"])
        alone += [r["fixes_per_s"] for r in doc["fleet"]["robots"]]
    headers = ["seed", "mean error over robots", "worst robot", "fixes/s per robot"]
    return "\n\n".join(
        [
            command_block(commands),
            table(headers, rows),
            f"Each robot got {span(rates, 1)} fixes per second; one robot alone on the site, "
            f"{span(alone, 1)}.",
        ]
    )


def live(run):
    """Three robots on the live mesh (`ickon sim`), seeds 1-3."""
    seeds = [1] if run.quick else [1, 2, 3]
    duration = "5" if run.quick else "20"
    rows, commands = [], []
    for seed in seeds:
        args = ["sim", "--robots", "3", "--duration", duration, "--seed", str(seed)]
        commands.append("ickon " + " ".join(args))
        doc, _ = run.ickon_json(args + ["--json"])
        for r in doc["robots"]:
            rows.append(
                [
                    str(seed),
                    r["id"],
                    fmt(r.get("mean_mm"), 1, "mm"),
                    fmt(r.get("p95_mm"), 1, "mm"),
                    fmt(r.get("fixes_per_s"), 2),
                    fmt(doc["cycles_per_s"], 2),
                    fmt(doc["firing_plan"]["transmitters_per_cycle"], 1)
                    if doc.get("firing_plan")
                    else "all",
                ]
            )
    headers = ["seed", "robot", "mean error", "p95", "fixes/s", "cycles/s", "transmitters a cycle"]
    return command_block(commands) + "\n\n" + table(headers, rows)


UTIL_FLIGHTS = [
    ("util", "const1-trial1-tdoa2", "anchors.csv", ["--constellation", "1"]),
    ("util", "const2-trial1-tdoa2", "anchors.csv", ["--constellation", "2"]),
    ("util", "const1-trial1-tdoa3", "anchors.csv", ["--constellation", "1"]),
    ("util-imu", "pre0425-traj1-tdoa2", "anchors_0425.csv", ["--imu"]),
    ("util-imu", "pre0425-traj7-tdoa2", "anchors_0425.csv", ["--imu"]),
    ("util-imu", "pre0426-traj4-tdoa2", "anchors_0426.csv", ["--imu"]),
    ("util-imu", "early-test-log00", "anchors_0607.csv", ["--imu"]),
]


def _util_rows(flight, doc):
    """The table's rows of one flight, the best RMSE and worst moment in bold."""
    ests = doc["estimators"]
    scored = [e for e in ests if e.get("rmse_3d_m") is not None]
    best_rmse = min((e["rmse_3d_m"] for e in scored), default=None)
    best_max = min((e["max_3d_m"] for e in scored), default=None)
    rows = []
    for i, e in enumerate(ests):
        name = f"`{e['name']}`" + (" (baseline)" if e["name"] == "cv-ekf" else "")
        rmse, worst = fmt(e.get("rmse_3d_m"), 3, "m"), fmt(e.get("max_3d_m"), 3, "m")
        if e.get("rmse_3d_m") is not None and e["rmse_3d_m"] == best_rmse:
            rmse = f"**{rmse}**"
        if e.get("max_3d_m") is not None and e["max_3d_m"] == best_max:
            worst = f"**{worst}**"
        nees = e.get("nees") or {}
        rows.append(
            [
                flight if i == 0 else "",
                name,
                rmse,
                fmt(e.get("rmse_xy_m"), 3, "m"),
                fmt(e.get("p95_3d_m"), 3, "m"),
                worst,
                fmt(e.get("output_began_s"), 2, "s"),
                fmt(e.get("rejected_pct"), 2, "%"),
                fmt(e.get("inside_95_pct"), 0, "%"),
                fmt(nees.get("mean"), 1),
                fmt(e.get("wall_s"), 2, "s"),
            ]
        )
    return rows


def _imu_row(flight, doc):
    """`imu-eskf`'s attitude and both filters' tracking after take-off."""
    by_name = {e["name"]: e for e in doc["estimators"]}
    eskf = by_name.get("imu-eskf") or {}
    att = eskf.get("attitude") or {}
    return [
        flight,
        fmt(att.get("rmse_deg"), 2, "deg"),
        f"{fmt(att.get('tilt_rmse_deg'), 2)} / {fmt(att.get('yaw_rmse_deg'), 2)} deg",
        fmt(att.get("max_deg"), 1, "deg"),
        fmt((by_name.get("tdoa-ekf") or {}).get("tracking_after_take_off_s"), 3, "s"),
        fmt(eskf.get("tracking_after_take_off_s"), 3, "s"),
    ]


def _util_flight(run, flight, thin=None):
    """One replay of a UTIL flight: its command line and its JSON."""
    sub, name, anchors, extra = flight
    folder = run.need_data(sub)
    args = ["replay", "util"] + [a for a in extra if a == "--imu"]
    args += ["--data", f"{folder}/{name}.csv", "--anchors", f"{folder}/{anchors}"]
    args += [a for a in extra if a != "--imu"]
    args += ["--thin", "3", "--thin-phase", str(thin)] if thin is not None else []
    args += ["--max-seconds", "8"] if run.quick else []
    shown = "ickon " + " ".join(args).replace(folder, "$ICKON_DATA/" + sub)
    doc, _ = run.ickon_json(args + ["--json"])
    return shown, doc


def _thinned(run, commands):
    """The first IMU flight at a third of its rate, three phases."""
    rows = []
    for phase in (0, 1, 2):
        shown, doc = _util_flight(run, UTIL_FLIGHTS[3], thin=phase)
        commands.append(shown)
        by_name = {e["name"]: e for e in doc["estimators"]}
        rows.append(
            [str(phase)]
            + [
                f"{fmt(by_name[n].get('rmse_3d_m'), 3)} / {fmt(by_name[n].get('max_3d_m'), 2)} m"
                for n in ("tdoa-ekf", "imu-eskf")
            ]
        )
    headers = ["`--thin-phase`", "`tdoa-ekf` RMSE / max", "`imu-eskf` RMSE / max"]
    return table(headers, rows)


def util(run):
    """The UTIL flights (UWB TDOA, motion-capture truth), every 3D filter."""
    flights = [UTIL_FLIGHTS[0], UTIL_FLIGHTS[3]] if run.quick else UTIL_FLIGHTS
    rows, imu_rows, commands = [], [], []
    for flight in flights:
        shown, doc = _util_flight(run, flight)
        commands.append(shown)
        label = flight[1] + (" (`--imu`)" if "--imu" in flight[3] else "")
        rows += _util_rows(label, doc)
        if "--imu" in flight[3]:
            imu_rows.append(_imu_row(flight[1], doc))
    headers = ["flight", "estimator", "3D RMSE", "xy RMSE", "p95 3D", "max 3D"]
    headers += ["output began", "rejected", "truth inside 95 %", "NEES", "time"]
    note = (
        "`truth inside 95 %` is the share of estimates whose truth lies inside the "
        "filter's 95 % ellipsoid (95 if its covariance is honest), `NEES` the average "
        "3D normalised estimation error squared (3 if honest), `time` the estimator's "
        "own wall time for the whole flight (this machine, build and load)."
    )
    parts = [table(headers, rows), note]
    if imu_rows:
        headers = ["IMU flight", "`imu-eskf` attitude RMS", "tilt / yaw RMS", "worst"]
        headers += ["`tdoa-ekf` tracking after take-off", "`imu-eskf` tracking after take-off"]
        parts += [
            "The IMU filter's attitude, and how soon after take-off each filter tracks "
            "(within 0.5 m for the next second):",
            table(headers, imu_rows),
        ]
    if not run.quick:
        thinned = _thinned(run, commands)
        parts += ["`pre0425-traj1-tdoa2` replayed at a third of its rate, three nearly "
                  "independent runs (`--thin 3 --thin-phase K`):", thinned]
    return "\n\n".join([command_block(commands)] + parts)


def plaza(run):
    """The CMU Plaza runs: a wheeled robot's odometry and radio ranges."""
    folder = run.need_data("plaza")
    commands = ["ickon replay plaza --data $ICKON_DATA/plaza"]
    doc, _ = run.ickon_json(["replay", "plaza", "--data", folder, "--json"])
    rows = []
    for r in doc["runs"]:
        for i, (track, key) in enumerate([("`tdoa-ekf`", "filter"), ("odometry", "odometry")]):
            e = r[key]
            bias = f"{r['range_bias_m']:.2f} m / {r['range_scale']:.3f}" if i == 0 else ""
            # Only the filter publishes a covariance; null when a pose had none.
            inside, nees = "", ""
            if i == 0:
                inside = "-" if r["inside_95_pct"] is None else f"{r['inside_95_pct']:.1f}"
                n = r["nees"]
                nees = "-" if n is None else f"{n['mean']:.2f} ({n['low']:.2f}-{n['high']:.2f})"
            rows.append(
                [
                    r["run"] if i == 0 else "",
                    track,
                    fmt(e["rmse_m"], 2, "m"),
                    fmt(e["mean_m"], 2, "m"),
                    fmt(e["p95_m"], 2, "m"),
                    fmt(e["max_m"], 2, "m"),
                    bias,
                    inside,
                    nees,
                ]
            )
    headers = ["run", "track", "RMSE", "mean", "p95", "max", "range bias / scale",
               "inside 95 %", "NEES (95 % bounds)"]
    return command_block(commands) + "\n\n" + table(headers, rows)


SECTIONS = {
    "lab": ("Accuracy on `lab` (simulation)", lab),
    "paper": ("The ICKON paper's schedule on `lab`", paper),
    "warehouse": ("Accuracy on `warehouse`, one robot per route", warehouse),
    "fleet": ("Accuracy on `warehouse`, a fleet of 16", fleet),
    "live": ("Accuracy on the live mesh", live),
    "util": ("Real data: UTIL flights", util),
    "plaza": ("Real data: CMU Plaza", plaza),
}
