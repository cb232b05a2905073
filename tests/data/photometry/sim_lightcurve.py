#!/usr/bin/env python3
"""An independent light-curve simulator for glint's [001] tests (plain Python, no glint code).

A box with one panel (shapes/box-panel.obj, scaled 1.2 in length) spins about an inertially
fixed axis in GEO, seen from a ground station over 20 minutes at 2 s cadence. The BRDF is
Ashikhmin-Shirley with Linares 2014's denominator (written here from the formulas), and the
shadowing is finer than glint's facet-centre test: each face is cut into 3 x 3 sub-faces, each
lit and seen by its own ray casts. Magnitude noise 0.05 mag. Writes LC.csv in glint's format
(t_s, mag, sigma_mag, sun_x.., obs_x.., range_m) and TRUTH.json / TRUTH.csv.

    python3 sim_lightcurve.py  (from this directory; rewrites the three files)
"""
import json, math, random

SCALE = 1.2
AXIS = (0.36, -0.48, 0.8)
SPIN = 2 * math.pi / 150.0  # rad/s
PHI0 = 0.9
SIGMA = 0.05
MAT = dict(rd=0.3, rs=0.5, nu=100.0, nv=100.0)
R_GEO, R_E, W_E = 42164e3, 6378e3, 7.2921159e-5


def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def add(a, b): return (a[0] + b[0], a[1] + b[1], a[2] + b[2])
def mul(a, k): return (a[0] * k, a[1] * k, a[2] * k)
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a): return math.sqrt(dot(a, a))
def unit(a): return mul(a, 1.0 / norm(a))


def load_obj(path):
    vs, faces = [], []
    for line in open(path):
        w = line.split()
        if not w: continue
        if w[0] == "v": vs.append(tuple(float(x) * SCALE for x in w[1:4]))
        if w[0] == "f": faces.append([vs[int(x.split("/")[0]) - 1] for x in w[1:]])
    return faces


def rotate(q, v):  # Hamilton q = (w, x, y, z), body -> inertial
    w, x, y, z = q
    u = (x, y, z)
    t = mul(cross(u, v), 2.0)
    return add(add(v, mul(t, w)), cross(u, t))


def quat(axis, angle):
    s = math.sin(angle / 2)
    return (math.cos(angle / 2), axis[0] * s, axis[1] * s, axis[2] * s)


def conj(q): return (q[0], -q[1], -q[2], -q[3])


def ray_hits_triangle(o, d, a, b, c):
    e1, e2 = sub(b, a), sub(c, a)
    p = cross(d, e2)
    det = dot(e1, p)
    if abs(det) < 1e-14: return False
    inv = 1.0 / det
    tv = sub(o, a)
    u = dot(tv, p) * inv
    if u < 0 or u > 1: return False
    qv = cross(tv, e1)
    v = dot(d, qv) * inv
    if v < 0 or u + v > 1: return False
    return dot(e2, qv) * inv > 1e-6


def rho(n, uu, vv, s, o):
    ns, no = dot(n, s), dot(n, o)
    if ns <= 0 or no <= 0: return 0.0
    rd, rs, nu, nv = MAT["rd"], MAT["rs"], MAT["nu"], MAT["nv"]
    diff = 28 * rd / (23 * math.pi) * (1 - rs) * (1 - (1 - ns / 2) ** 5) * (1 - (1 - no / 2) ** 5)
    h = unit(add(s, o))
    nh = dot(n, h)
    sin2 = 1 - nh * nh
    z = (nu + nv) / 2 if sin2 < 1e-12 else (nu * dot(h, uu) ** 2 + nv * dot(h, vv) ** 2) / sin2
    f = rs + (1 - rs) * (1 - dot(s, h)) ** 5
    spec = math.sqrt((nu + 1) * (nv + 1)) / (8 * math.pi) * max(nh, 0) ** z / (ns + no - ns * no) * f
    return diff + spec


def main():
    faces = load_obj("../../../shapes/box-panel.obj")
    tris = []  # every face fanned, for the ray casts
    subs = []  # (centre, area, n, u, v, face index)
    for k, f in enumerate(faces):
        for i in range(1, len(f) - 1): tris.append((k, f[0], f[i], f[i + 1]))
        n = unit(cross(sub(f[1], f[0]), sub(f[2], f[0])))
        uu = unit(sub(f[1], f[0]))
        vv = cross(n, uu)
        # quads: 3 x 3 bilinear sub-faces
        a, b, c, d = f
        for i in range(3):
            for j in range(3):
                def at(s, t): return add(add(mul(a, (1 - s) * (1 - t)), mul(b, s * (1 - t))), add(mul(c, s * t), mul(d, (1 - s) * t)))
                p00, p10, p11, p01 = at(i / 3, j / 3), at((i + 1) / 3, j / 3), at((i + 1) / 3, (j + 1) / 3), at(i / 3, (j + 1) / 3)
                centre = mul(add(add(p00, p10), add(p11, p01)), 0.25)
                area = 0.5 * norm(cross(sub(p11, p00), sub(p01, p10)))
                subs.append((centre, area, n, uu, vv, k))
    axis = unit(AXIS)
    sun_i = unit((-0.8, 0.5, 0.2))
    lat, lon = math.radians(30.0), math.radians(10.0)
    rnd = random.Random(1)
    lc = ["t_s,mag,sigma_mag,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m"]
    truth_rows = ["t_s,qw,qx,qy,qz"]
    for k in range(600):
        t = 2.0 * k
        th = W_E * t
        sat = (R_GEO * math.cos(th), R_GEO * math.sin(th), 0.0)
        st = (R_E * math.cos(lat) * math.cos(lon + th), R_E * math.cos(lat) * math.sin(lon + th), R_E * math.sin(lat))
        los = sub(st, sat)
        rng = norm(los)
        obs_i = unit(los)
        q = quat(axis, PHI0 + SPIN * t)
        qi = conj(q)
        s_b, o_b = rotate(qi, sun_i), rotate(qi, obs_i)
        total = 0.0
        for centre, area, n, uu, vv, face in subs:
            ns, no = dot(n, s_b), dot(n, o_b)
            if ns <= 0 or no <= 0: continue
            o = add(centre, mul(n, 1e-6))
            if any(tf != face and ray_hits_triangle(o, s_b, a, b, c) for tf, a, b, c in tris): continue
            if any(tf != face and ray_hits_triangle(o, o_b, a, b, c) for tf, a, b, c in tris): continue
            total += rho(n, uu, vv, s_b, o_b) * area * ns * no
        truth_rows.append("%g,%.12f,%.12f,%.12f,%.12f" % ((t,) + q))
        if total <= 0: continue  # no light: absent, as the format says
        mag = -26.7 - 2.5 * math.log10(total / rng ** 2) + rnd.gauss(0, SIGMA)
        lc.append("%g,%.6f,%g,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.3f" % ((t, mag, SIGMA) + sun_i + obs_i + (rng,)))
    open("LC.csv", "w").write("\n".join(lc) + "\n")
    open("TRUTH.csv", "w").write("\n".join(truth_rows) + "\n")
    json.dump({"geometry": "box-panel", "axis": list(axis), "spin_rad_s": SPIN,
               "area_scale": SCALE ** 2, "sigma_mag": SIGMA}, open("TRUTH.json", "w"), indent=2)


if __name__ == "__main__":
    main()
