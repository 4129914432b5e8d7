"""What the site generators (`make_hall.py`, `make_warehouse.py`) share:
number formatting for the TOML they write, arc length along a closed route,
and how robots are spread over the routes."""

import math


def fmt(v):
    return f"{v:.3f}".rstrip("0").rstrip(".") if v != int(v) else f"{v:.1f}"


def pt(p):
    return f"[{fmt(p[0])}, {fmt(p[1])}]"


def length(points):
    n = len(points)
    return sum(((points[(i + 1) % n][0] - points[i][0]) ** 2 + (points[(i + 1) % n][1] - points[i][1]) ** 2) ** 0.5
               for i in range(n))


def along(points, s):
    """Point and heading (deg) at arc length s of a closed polyline."""
    n = len(points)
    s %= length(points)
    for i in range(n):
        p, q = points[i], points[(i + 1) % n]
        d = math.hypot(q[0] - p[0], q[1] - p[1])
        if s < d:
            t = s / d
            return (p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]),
                    math.degrees(math.atan2(q[1] - p[1], q[0] - p[0])))
        s -= d
    raise AssertionError


def van_der_corput(m):
    """0, 1/2, 1/4, 3/4, ...: the first few robots of a route are spread along it."""
    v, denom = 0.0, 1.0
    while m:
        denom *= 2
        v += (m & 1) / denom
        m >>= 1
    return v


def robots(route_list):
    """`(id, route, (x, y, heading_deg))` for every robot of `route_list`
    (`(name, points, robots)` each), round robin over the routes so that the
    first N robots (`--robots N`) spread over all of them."""
    members = {name: 0 for name, _, _ in route_list}
    out = []
    while True:
        added = False
        for name, points, cap in route_list:
            m = members[name]
            if m >= cap:
                continue
            members[name] = m + 1
            # Offset by a quarter of the route's spacing so that no robot starts on a corner.
            s = length(points) * (van_der_corput(m) + 0.25 / cap)
            x, y, h = along(points, s)
            out.append((f"r{len(out) + 1}", name, (x, y, h)))
            added = True
        if not added:
            return out
