#!/usr/bin/env python3
"""An independent stereo relative-navigation simulator (standard library only), written to
check `glint tool relnav` on files glint did not make.

It shares no code with glint and uses other conventions inside: Shuster's scalar-last
quaternion q_ti with A(q) = C_TI (Markley & Crassidis 2014, eq 3 of the paper), q' = 1/2 Xi(q) w,
Euler's equations with the inertia itself, the Hill/CW solution in closed form. It writes the
files of glint's fixed formats:

  RIG.toml   the rig (no initial state: glint starts from the measurements)
  MEAS.csv   t_s, feature, x_l, y_l, x_r, y_r   (here in another column order, with a comment)
  TRUTH.csv  t_s, qw, qx, qy, qz (Hamilton q_ct, R = C_CT), wx, wy, wz, rho_x.., v_x..; and
             the true k in a comment

Usage: sim_stereo.py OUTDIR [--seed N]
"""
import math
import os
import random
import sys

N_RAD_S = 1.1068e-3          # 500 km circular orbit
DT_S = 5.0                   # epoch period
DURATION_S = 6000.0
H_S = 0.05                   # RK4 step of the truth
BASELINE_M = 0.5
SIGMA = 1e-5
J = (20.0, 25.0, 32.0)       # principal moments [kg m^2]
W0 = (0.03, 0.02, -0.04)     # target inertial rate in T at t = 0 [rad/s]
RHO0 = (0.3, 12.0, -0.2)     # target CoM relative to the camera, O = RSW [m]
V0 = (-0.0015, -2.0 * N_RAD_S * 0.3, 0.0008)
FEATURES = [(0.6, 0.0, 0.0), (-0.6, 0.1, 0.0), (0.0, 0.6, 0.2), (0.1, -0.5, 0.3), (0.0, 0.0, 0.6)]
C_CO = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
DROPOUT = 0.1
WRONG_MATCH = 0.02


def matmul(a, b):
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))


def matvec(a, v):
    return tuple(sum(a[i][k] * v[k] for k in range(3)) for i in range(3))


def transpose(a):
    return tuple(tuple(a[j][i] for j in range(3)) for i in range(3))


def shuster_a(q):
    """A(q) = (q4^2 - |e|^2) I - 2 q4 [e x] + 2 e e^T, q = (e1, e2, e3, q4)."""
    e1, e2, e3, q4 = q
    s = q4 * q4 - (e1 * e1 + e2 * e2 + e3 * e3)
    e = (e1, e2, e3)
    cx = ((0.0, -e3, e2), (e3, 0.0, -e1), (-e2, e1, 0.0))
    return tuple(
        tuple((s if i == j else 0.0) - 2.0 * q4 * cx[i][j] + 2.0 * e[i] * e[j] for j in range(3))
        for i in range(3)
    )


def shuster_from_a(a):
    """The scalar-last quaternion with A(q) = a (largest-component method)."""
    tr = a[0][0] + a[1][1] + a[2][2]
    cands = [tr, a[0][0], a[1][1], a[2][2]]
    i = max(range(4), key=lambda k: cands[k])
    if i == 0:
        q4 = 0.5 * math.sqrt(1.0 + tr)
        e = ((a[1][2] - a[2][1]) / (4 * q4), (a[2][0] - a[0][2]) / (4 * q4), (a[0][1] - a[1][0]) / (4 * q4))
        return (e[0], e[1], e[2], q4)
    j, k = {1: (1, 2), 2: (2, 0), 3: (0, 1)}[i]
    m = i - 1
    em = 0.5 * math.sqrt(1.0 + 2.0 * a[m][m] - tr)
    q4 = (a[j][k] - a[k][j]) / (4 * em)
    e = [0.0, 0.0, 0.0]
    e[m] = em
    e[j] = (a[m][j] + a[j][m]) / (4 * em)
    e[k] = (a[m][k] + a[k][m]) / (4 * em)
    return (e[0], e[1], e[2], q4)


def deriv(q, w):
    e1, e2, e3, q4 = q
    wx, wy, wz = w
    # q' = 1/2 Xi(q) w, Xi = [q4 I + [e x]; -e^T]
    dq = (
        0.5 * (q4 * wx - e3 * wy + e2 * wz),
        0.5 * (e3 * wx + q4 * wy - e1 * wz),
        0.5 * (-e2 * wx + e1 * wy + q4 * wz),
        -0.5 * (e1 * wx + e2 * wy + e3 * wz),
    )
    jx, jy, jz = J
    dw = ((jy - jz) / jx * wy * wz, (jz - jx) / jy * wz * wx, (jx - jy) / jz * wx * wy)
    return dq, dw


def rk4(q, w, h):
    def add(a, b, s):
        return tuple(x + s * y for x, y in zip(a, b))
    q1, w1 = deriv(q, w)
    q2, w2 = deriv(add(q, q1, h / 2), add(w, w1, h / 2))
    q3, w3 = deriv(add(q, q2, h / 2), add(w, w2, h / 2))
    q4, w4 = deriv(add(q, q3, h), add(w, w3, h))
    q = tuple(q[i] + h / 6 * (q1[i] + 2 * q2[i] + 2 * q3[i] + q4[i]) for i in range(4))
    w = tuple(w[i] + h / 6 * (w1[i] + 2 * w2[i] + 2 * w3[i] + w4[i]) for i in range(3))
    nq = math.sqrt(sum(x * x for x in q))
    return tuple(x / nq for x in q), w


def cw(t):
    """Hill/CW closed form in RSW from (RHO0, V0)."""
    n = N_RAD_S
    s, c = math.sin(n * t), math.cos(n * t)
    x0, y0, z0 = RHO0
    vx, vy, vz = V0
    x = (4 - 3 * c) * x0 + s / n * vx + 2 * (1 - c) / n * vy
    y = 6 * (s - n * t) * x0 + y0 - 2 * (1 - c) / n * vx + (4 * s - 3 * n * t) / n * vy
    z = c * z0 + s / n * vz
    dx = 3 * n * s * x0 + c * vx + 2 * s * vy
    dy = -6 * n * (1 - c) * x0 - 2 * s * vx + (4 * c - 3) * vy
    dz = -n * s * z0 + c * vz
    return (x, y, z), (dx, dy, dz)


def c_io(t):
    s, c = math.sin(N_RAD_S * t), math.cos(N_RAD_S * t)
    return ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))


def main():
    out = sys.argv[1]
    seed = int(sys.argv[sys.argv.index("--seed") + 1]) if "--seed" in sys.argv else 2026
    rng = random.Random(seed)
    os.makedirs(out, exist_ok=True)
    # attitude at t = 0: C_TC from a rotation of 50 deg about (1, 2, -1), then C_TI = C_TC C_CI
    ax = (1.0, 2.0, -1.0)
    na = math.sqrt(sum(x * x for x in ax))
    half = math.radians(50.0) / 2
    q_tc0 = tuple(math.sin(half) * x / na for x in ax) + (math.cos(half),)
    c_ci0 = matmul(C_CO, transpose(c_io(0.0)))
    q = shuster_from_a(matmul(shuster_a(q_tc0), c_ci0))
    w = W0
    t = 0.0
    meas = ["# written by tests/data/relnav/sim_stereo.py (an independent simulator)",
            "feature,t_s,x_r,y_r,x_l,y_l"]
    truth = ["# k1 = %.12f, k2 = %.12f" % (
        0.5 * math.log((J[0] + J[1] - J[2]) / (J[0] - J[1] + J[2])),
        0.5 * math.log((J[1] + J[2] - J[0]) / (J[1] - J[2] + J[0]))),
        "t_s,qw,qx,qy,qz,wx,wy,wz,rho_x,rho_y,rho_z,v_x,v_y,v_z"]
    steps = int(round(DT_S / H_S))
    epochs = int(DURATION_S / DT_S) + 1
    for k in range(epochs):
        if k > 0:
            for _ in range(steps):
                q, w = rk4(q, w, H_S)
            t = k * DT_S
        rho, v = cw(t)
        c_ti = shuster_a(q)
        c_tc = matmul(c_ti, matmul(c_io(t), transpose(C_CO)))
        c_ct = transpose(c_tc)
        qs = shuster_from_a(c_tc)  # Shuster q_tc = Hamilton q_ct reordered
        if qs[3] < 0:
            qs = tuple(-x for x in qs)
        truth.append(",".join("%.12e" % x for x in (t, qs[3], qs[0], qs[1], qs[2]) + w + rho + v))
        rows = []
        for i, r in enumerate(FEATURES):
            p = tuple(a + b for a, b in zip(matvec(C_CO, rho), matvec(c_ct, r)))
            z = (p[0] / p[2], p[1] / p[2], (p[0] - BASELINE_M) / p[2], p[1] / p[2])
            z = tuple(x + rng.gauss(0.0, SIGMA) for x in z)
            if rng.random() < DROPOUT:
                continue
            rows.append([i, z])
        if rows and rng.random() < WRONG_MATCH:
            j = rng.randrange(len(rows))
            rows[j][0] = (rows[j][0] + 1 + rng.randrange(len(FEATURES) - 1)) % len(FEATURES)
        for i, z in rows:
            meas.append("%d,%.3f,%.12e,%.12e,%.12e,%.12e" % (i, t, z[2], z[3], z[0], z[1]))
    with open(os.path.join(out, "MEAS.csv"), "w") as f:
        f.write("\n".join(meas) + "\n")
    with open(os.path.join(out, "TRUTH.csv"), "w") as f:
        f.write("\n".join(truth) + "\n")
    with open(os.path.join(out, "RIG.toml"), "w") as f:
        f.write("# written by sim_stereo.py\n")
        f.write("mean_motion_rad_s = %r\n" % N_RAD_S)
        f.write("baseline_m = %r\n" % BASELINE_M)
        f.write("sigma_norm = %r\n" % SIGMA)
        f.write("c_co = [[1,0,0],[0,0,-1],[0,1,0]]\n")
        f.write("features_m = [%s]\n" % ", ".join("[%r, %r, %r]" % r for r in FEATURES))


if __name__ == "__main__":
    main()
