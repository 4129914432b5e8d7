#!/usr/bin/env python3
"""Writes deploy/sites/warehouse.toml, the second built-in site.

The file is generated because 16 cells, 64 transmitters, 7 routes and 128
robots are too many to keep consistent by hand; the layout is the numbers
below. Run `python3 deploy/sites/make_warehouse.py > deploy/sites/warehouse.toml`
and commit both; `ickon site check --site warehouse` validates the result and
`proto/src/site/tests.rs` checks its coverage and routes.
"""

AISLES = 4  # aisles along x, separated by rack rows
AISLE_W = 3.0  # aisle width, m
RACK_D = 1.2  # rack row depth, m
LENGTH = 40.0  # floor length, m
CROSS = 4.0  # cross-aisle at each end (no racks), m
SEGMENTS = 4  # cells per aisle
RACK_H = 5.0  # racks block sound up to here
CEILING = 6.0
TX_Z = (4.2, 4.4)  # transmitters hang below the rack tops: racks block them
ROBOTS_PER_AISLE_LOOP = 20
ROBOTS_PER_RACK_LOOP = 16


def aisle_y(k):
    return k * (AISLE_W + RACK_D)


def fmt(v):
    return f"{v:.3f}".rstrip("0").rstrip(".") if v != int(v) else f"{v:.1f}"


def pt(p):
    return f"[{fmt(p[0])}, {fmt(p[1])}]"


def cells():
    out = []
    seg = LENGTH / SEGMENTS
    for k in range(AISLES):
        a = aisle_y(k)
        top = a + AISLE_W
        strip = a + AISLE_W + RACK_D  # the cross-aisle strip up to the next aisle
        for s in range(SEGMENTS):
            x0, x1 = s * seg, (s + 1) * seg
            has_strip = k < AISLES - 1
            if s == 0 and has_strip:
                poly = [(x0, a), (x1, a), (x1, top), (CROSS, top), (CROSS, strip), (x0, strip)]
            elif s == SEGMENTS - 1 and has_strip:
                poly = [(x0, a), (x1, a), (x1, strip), (LENGTH - CROSS, strip), (LENGTH - CROSS, top), (x0, top)]
            else:
                poly = [(x0, a), (x1, a), (x1, top), (x0, top)]
            cid = f"c{k + 1}{s + 1}"
            txs = []
            for j, (dx, dy) in enumerate([(1.5, 0.6), (seg - 1.5, 0.6), (seg - 1.5, AISLE_W - 0.6), (1.5, AISLE_W - 0.6)]):
                txs.append((100 * (k + 1) + 10 * (s + 1) + j + 1, (x0 + dx, a + dy, TX_Z[j % 2])))
            out.append((cid, poly, txs))
    return out


def racks():
    return [
        [(CROSS, aisle_y(k) + AISLE_W), (LENGTH - CROSS, aisle_y(k) + AISLE_W),
         (LENGTH - CROSS, aisle_y(k + 1)), (CROSS, aisle_y(k + 1))]
        for k in range(AISLES - 1)
    ]


def pillars():
    """Building pillars in the cross-aisles, on the rack rows' lines."""
    out = []
    for k in range(AISLES - 1):
        yc = aisle_y(k) + AISLE_W + RACK_D / 2
        for xc in (1.2, LENGTH - 1.2):
            out.append([(xc - 0.2, yc - 0.2), (xc + 0.2, yc - 0.2), (xc + 0.2, yc + 0.2), (xc - 0.2, yc + 0.2)])
    return out


def routes():
    out = []
    for k in range(AISLES):
        a = aisle_y(k)
        out.append((f"aisle-{k + 1}", [(2.5, a + 1.0), (LENGTH - 2.5, a + 1.0), (LENGTH - 2.5, a + 2.0), (2.5, a + 2.0)],
                    ROBOTS_PER_AISLE_LOOP))
    for k in range(AISLES - 1):
        lo = aisle_y(k) + AISLE_W - 0.6
        hi = aisle_y(k + 1) + 0.6
        out.append((f"rack-{k + 1}", [(2.5, lo), (LENGTH - 2.5, lo), (LENGTH - 2.5, hi), (2.5, hi)],
                    ROBOTS_PER_RACK_LOOP))
    return out


def length(points):
    n = len(points)
    return sum(((points[(i + 1) % n][0] - points[i][0]) ** 2 + (points[(i + 1) % n][1] - points[i][1]) ** 2) ** 0.5
               for i in range(n))


def along(points, s):
    """Point and heading (deg) at arc length s of a closed polyline."""
    import math
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
    # Round robin over the routes, so that the first N robots (`--robots N`)
    # spread over every aisle and rack loop.
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


def main():
    cs = cells()
    rs = routes()
    print(f"""# The built-in `warehouse` site: {AISLES} aisles of {fmt(AISLE_W)} m between rack rows,
# {LENGTH:.0f} m long, with cross-aisles of {CROSS:.0f} m at both ends; {AISLES * SEGMENTS} cells,
# {len(cs) * 4} transmitters, {len(rs)} loop routes and {sum(r[2] for r in rs)} robots on them.
# Generated by deploy/sites/make_warehouse.py (edit the script, not this file);
# the format is documented in deploy/sites/lab.toml.
#
#   y    aisle 4: cells c41 c42 c43 c44 (x 0-10-20-30-40)
#  15.6 +---------------------------------------------+
#       |                                             |
#  12.6 |  p  +=================================+  p  |   rack row 3 (x 4-36)
#  11.4 |     +=================================+     |
#       |       aisle 3: c31 c32 c33 c34              |
#   8.4 |  p  +=================================+  p  |   rack row 2
#   7.2 |     +=================================+     |
#       |       aisle 2: c21 c22 c23 c24              |
#   4.2 |  p  +=================================+  p  |   rack row 1
#   3.0 |     +=================================+     |
#       |       aisle 1: c11 c12 c13 c14              |
#     0 +---------------------------------------------+
#       0  p: pillar (x 1.2, 38.8)  4              36   40  x
#
# The racks reach 5 m and the transmitters hang at 4.2-4.4 m, so a rack row
# blocks the sound between two aisles: cells of neighbouring aisles interfere
# only through the cross-aisles, and the schedule reuses slots along the aisles.
# The end cells of aisles 1-3 also cover the cross-aisle strip beside their
# rack row.

name = "warehouse"
temperature_c = 20.0
guard_time_ms = 10.0
ceiling_height_m = {fmt(CEILING)}

[msu]
receivers = 6
receiver_angles_deg = [0.0, 60.0, 120.0, 180.0, 240.0, 300.0]
height_m = 0.5
""")
    for cid, poly, _ in cs:
        print(f"[[cells]]\nid = \"{cid}\"\npolygon = [{', '.join(pt(p) for p in poly)}]\n")
    for cid, _, txs in cs:
        for tid, (x, y, z) in txs:
            print(f"[[transmitters]]\nid = {tid}\ncell = \"{cid}\"\nposition = [{fmt(x)}, {fmt(y)}, {z:.2f}]\n")
    print("# Outer walls.")
    w, h = LENGTH, aisle_y(AISLES - 1) + AISLE_W
    for a, b in [((0, 0), (w, 0)), ((w, 0), (w, h)), ((w, h), (0, h)), ((0, h), (0, 0))]:
        print(f"[[walls]]\nfrom = {pt(a)}\nto = {pt(b)}\n")
    print(f"# Rack rows: {fmt(RACK_H)} m high, they block sound and robots.")
    for poly in racks():
        print(f"[[columns]]\npolygon = [{', '.join(pt(p) for p in poly)}]\nheight_m = {fmt(RACK_H)}\n")
    print("# Building pillars in the cross-aisles.")
    for poly in pillars():
        print(f"[[columns]]\npolygon = [{', '.join(pt(p) for p in poly)}]\n")
    print("# aisle-N: out along aisle N and back on its other lane; rack-N: around rack row N\n"
          "# through both cross-aisles.")
    for name, points, _ in rs:
        print(f"[[routes]]\nname = \"{name}\"\nclosed = true\npoints = [{', '.join(pt(p) for p in points)}]\n")
    print("# Robots: round robin over the routes, spread along each, so that the first N\n"
          "# (`ickon sim --robots N`) cover the whole floor. start = [x, y, heading_deg] on the route.")
    for rid, route, (x, y, hd) in robots(rs):
        print(f"[[robots]]\nid = \"{rid}\"\nroute = \"{route}\"\nstart = [{x:.3f}, {y:.3f}, {hd:.1f}]\n")


if __name__ == "__main__":
    main()
