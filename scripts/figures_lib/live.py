"""What the live-mesh sections read from an `ickon sim --json` report, and
the table columns they share.

Pose latency over a fleet: the median of the robots' medians (p50) and
the worst robot's 99th percentile (p99).
"""

from figures_lib.output import fmt, mean, median


def robots(doc):
    """The report's robots."""
    return doc.get("robots", [])


def fix_share(doc):
    """(worst, mean) share of the cycles a robot got a fix in, percent."""
    shares = [r["fix_share"] * 100 for r in robots(doc) if r.get("fix_share") is not None]
    return (min(shares) if shares else None, mean(shares))


def fired_worst(doc):
    """The lowest share of its due cycles a cell fired in, percent."""
    shares = [c["fired_share"] * 100 for c in doc.get("cells", []) if c.get("fired_share") is not None]
    return min(shares) if shares else None


def sync_max_us(doc):
    """The largest emission-time error of any cell, microseconds."""
    errs = [c["sync_error_max_us"] for c in doc.get("cells", []) if c.get("sync_error_max_us") is not None]
    return max(errs) if errs else None


def latency_ms(doc):
    """(median robot's p50, worst robot's p99) pose latency, milliseconds."""
    p50 = median(r.get("latency_p50_us") for r in robots(doc))
    p99s = [r["latency_p99_us"] for r in robots(doc) if r.get("latency_p99_us") is not None]
    return (p50 / 1e3 if p50 is not None else None, max(p99s) / 1e3 if p99s else None)


def mean_error_mm(doc):
    """The mean over the robots of each one's mean error, millimetres."""
    return mean(r.get("mean_mm") for r in robots(doc))


def fixes_per_s(doc):
    """The mean over the robots of each one's fixes per second."""
    return mean(r.get("fixes_per_s") for r in robots(doc))


def cost_cores(doc, side):
    """Cores used by `servers` or `simulation` while the run was watched."""
    part = (doc.get("cost") or {}).get(side) or {}
    return part.get("cores")


def process_cpu_s(doc, kind=None):
    """CPU seconds of every process of the run, or of one kind's."""
    return sum(p["cpu_s"] for p in doc.get("processes", []) if kind is None or p["kind"] == kind)


def process_peak_mib(doc, kind):
    """The largest peak memory of a process of `kind`, MiB."""
    peaks = [p["peak_rss_max_mib"] for p in doc.get("processes", []) if p["kind"] == kind]
    return max(peaks) if peaks else None


def agent(doc):
    """(CPU ms per second, peak MiB) of one robot's agent, or (None, None)."""
    a = (doc.get("cost") or {}).get("agent") or {}
    return a.get("cpu_ms_per_s"), a.get("peak_rss_mib")


def share_pair(doc):
    """`worst / mean %` of the robots' fix shares."""
    worst, avg = fix_share(doc)
    return f"{fmt(worst, 1)} / {fmt(avg, 1)} %"


def latency_pair(doc):
    """`p50 / p99 ms` of the pose latency."""
    p50, p99 = latency_ms(doc)
    return f"{fmt(p50, 1)} / {fmt(p99, 1)} ms"
