#!/usr/bin/env python3
"""An independent spectral light-curve simulator for the [000] attitude solve (Tan et al. 2020),
written from docs math.md §1 to check `glint invert` on files glint did not make. numpy only.

It shares no code with glint. What it models:

  Orbits     Table 1 of math.md §1.7 as two circular equatorial Kepler orbits (mu = 398600.4418
             km^3/s^2); the Table 1 elements hold at the motion start (t = t_m), the target's
             LVLH frame B is x along-track, y = -orbit normal, z nadir (C_BI rows h x r, -h, -r).
  Sun        inertially fixed over the pass, declination +0.124 deg, its right ascension chosen so
             that the phase angle angle(s, o) is 15 deg at the motion start, past the glint (s_z < 0);
             the stable window starts where the phase is 40 deg before the glint (s_z > 0).
  Signal     eqs (1)-(4): Phi_k = K A_k [n.s]+ [n.o]+ f_k, K = E_sun(lambda) A_ap / range^2, times the
             10-nm band width (flux in W); E_sun = pi B(lambda, 5778 K) (R_sun/1 AU)^2; A_ap = pi 0.1505^2/4.
             n_b = +x; n_p = normalize(s - (s.y) y) from the (true) Sun of each sample, held in B.
  BRDF       eqs (5)-(6): Cook-Torrance/Beckmann lobes with F = G = 1, h = normalize(s + o),
             tan^2 tau = (1 - c^2)/c^2; the area x BRDF products of math.md Table 4 at 650 nm
             (no diffuse term), scaled per band by a smooth reflectance (body: yellow film, rising to
             the red; panel: cells, falling slightly to the red), 1 at 650 nm.
  Motion     eqs (15)-(19), the verbatim matrices R = R_Z(psi) R_Y(phi) R_X(theta), theta = w_x t,
             phi = w_y t, psi = w_z t (t = frame index, frame 0 unrotated); s' = R s, o' = R o; the
             panel normal stays the one of eq (4) on the nominal (unrotated) Sun ("literal").
             The truth p = [w_x, w_y, w_z] deg/frame is therefore the rate glint reports (its
             default attitude = "verbatim"). Spin cases: x, y, z at 0.25 deg/frame.
  Sampling   stable window 600 samples evenly from phase 40 deg to the motion start (motion frame 0
             is one stable interval after the last stable sample); motion window 240 frames, 1 s apart.
  Bands      400, 450, ..., 750 nm (8 bands, not glint's 36).
  Noise      Gaussian, sigma = mean_t(Phi) / SNR per band and per window (math.md §1.7: mean over the
             window's samples of the noise-free band flux); numpy default_rng(SeedSequence(seed)),
             noise and perturbations on separate child streams, so --perturb leaves the noise draws.
  --perturb  what another tool (or the sky) would differ in: every lobe width mu_m of each facet
             times 1 +- U(5 %, 10 %) (sign random), each facet's area (all its products) times
             1 +- U(3 %, 5 %), and the true Sun 0.5 deg off the one written in the file (a rotation
             of 0.5 deg about a random axis perpendicular to it). The file states the nominal Sun.

It writes OUTDIR/observations.csv in glint's observation format (docs/observations.md), with
another column order and other accepted spellings (segment, frame, time_s, r_m, ox.., sx..,
flux<nm>, err_<nm>), comment lines, and the truth comment; --no-sigma leaves out the sigma
columns (same data). OUTDIR/TRUTH.json states the truth, the settings, the sigmas and every
perturbation drawn.

Usage: sim_spectral.py OUTDIR --axis {x,y,z} --snr S --seed N [--no-sigma] [--perturb]
       (--snr inf: noise-free)
"""
import argparse
import json
import math
import os

import numpy as np

MU_KM3_S2 = 398600.4418
A_TARGET_KM, L_TARGET_DEG = 42378.1, 181.803 + 0.0 + 0.0            # a; Omega + omega + nu
A_OBSERVER_KM, L_OBSERVER_DEG = 42408.0, 184.860 + 0.0 + 359.93
SUN_DEC_DEG = 0.124
START_PHASE_DEG = 15.0
STABLE_START_PHASE_DEG = 40.0
STABLE_SAMPLES = 600
MOTION_FRAMES = 240
FRAME_INTERVAL_S = 1.0
RATE_DEG_PER_FRAME = 0.25
BANDS_NM = [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 750.0]
BAND_WIDTH_NM = 10.0
PUPIL_D_M = 0.1505
T_SUN_K = 5778.0
R_SUN_M, AU_M = 6.957e8, 1.495978707e11
MU = np.array([0.01, 0.02, 0.04, 0.05, 0.07, 0.08, 0.10, 0.20, 0.30, 0.50])
BODY_650 = np.array([0.1722, 0.0248, 0.0102, 0.0517, 0.0312, 0.0083, 0.0137, 0.0077, 0.0002, 0.0])
PANEL_650 = np.array([0.0003, 0.0103, 0.0837, 0.1046, 0.8049, 0.1153, 0.0489, 0.0345, 0.0003, 0.0103])
N_BODY = np.array([1.0, 0.0, 0.0])
Y_AXIS = np.array([0.0, 1.0, 0.0])
SUN_OFFSET_DEG = 0.5


def body_reflectance(lam):
    """Yellow film: low in the blue, 1 at 650 nm."""
    f = lambda x: 0.45 + 0.55 / (1.0 + math.exp(-(x - 520.0) / 25.0))
    return f(lam) / f(650.0)


def panel_reflectance(lam):
    """Solar cells: slightly brighter in the blue, 1 at 650 nm."""
    return 1.0 + 0.25 * (650.0 - lam) / 250.0


def e_sun(lam_nm):
    """Solar spectral irradiance at 1 AU [W m^-2 nm^-1], a 5778 K black body."""
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    lam = lam_nm * 1e-9
    b = 2.0 * h * c * c / lam ** 5 / math.expm1(h * c / (lam * k * T_SUN_K))
    return math.pi * b * (R_SUN_M / AU_M) ** 2 * 1e-9


def mean_motion(a_km):
    return math.sqrt(MU_KM3_S2 / a_km ** 3)


def orbit_pos(a_km, l0_deg, dt_s):
    lon = math.radians(l0_deg) + mean_motion(a_km) * dt_s
    return a_km * 1e3 * np.array([math.cos(lon), math.sin(lon), 0.0]), lon


def c_bi(lon):
    """Rows: x = h x r (along-track), y = -h, z = -r (nadir); h = +Z inertial."""
    r = np.array([math.cos(lon), math.sin(lon), 0.0])
    h = np.array([0.0, 0.0, 1.0])
    return np.array([np.cross(h, r), -h, -r])


def geometry(dt_s, sun_i):
    """Body-frame Sun and observer unit vectors and the range [m], dt_s after the motion start."""
    rt, lon = orbit_pos(A_TARGET_KM, L_TARGET_DEG, dt_s)
    ro, _ = orbit_pos(A_OBSERVER_KM, L_OBSERVER_DEG, dt_s)
    c = c_bi(lon)
    d = ro - rt
    rng = float(np.linalg.norm(d))
    return c @ sun_i, c @ (d / rng), rng


def sun_inertial(ra_deg, dec_deg=SUN_DEC_DEG):
    a, d = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(d) * math.cos(a), math.cos(d) * math.sin(a), math.sin(d)])


def phase_deg(s, o):
    return math.degrees(math.acos(max(-1.0, min(1.0, float(s @ o)))))


def bisect(f, a, b, it=200):
    fa = f(a)
    for _ in range(it):
        m = 0.5 * (a + b)
        fm = f(m)
        if (fm > 0) == (fa > 0):
            a, fa = m, fm
        else:
            b = m
    return 0.5 * (a + b)


def solve_sun_ra():
    """RA with phase 15 deg at the motion start and the Sun past the glint (s_z < 0)."""
    def g(ra):
        s, o, _ = geometry(0.0, sun_inertial(ra))
        return phase_deg(s, o) - START_PHASE_DEG
    grid = np.arange(0.0, 360.0, 0.5)
    for a, b in zip(grid[:-1], grid[1:]):
        if (g(a) > 0) != (g(b) > 0):
            ra = bisect(g, a, b)
            s, o, _ = geometry(0.0, sun_inertial(ra))
            if s[2] < 0 and s[0] > 0:
                return ra
    raise RuntimeError("no Sun right ascension gives the start phase")


def stable_start(sun_i):
    """Seconds before the motion start where the phase is 40 deg with the Sun before the glint."""
    def g(dt):
        s, o, _ = geometry(dt, sun_i)
        return phase_deg(s, o) - STABLE_START_PHASE_DEG
    # the Sun moves about 15 deg/h through B; search back over half a day
    dts = -np.arange(0.0, 43200.0, 60.0)
    for a, b in zip(dts[:-1], dts[1:]):
        if (g(a) > 0) != (g(b) > 0):
            dt = bisect(g, b, a)
            if geometry(dt, sun_i)[0][2] > 0:
                return dt
    raise RuntimeError("no stable-window start")


def rot_verbatim(p_deg, t):
    """Eq (17) as printed: R_Z(psi) R_Y(phi) R_X(theta)."""
    th, ph, ps = (math.radians(x * t) for x in p_deg)
    rz = np.array([[math.cos(ps), math.sin(ps), 0], [-math.sin(ps), math.cos(ps), 0], [0, 0, 1]])
    ry = np.array([[math.cos(ph), 0, math.sin(ph)], [0, 1, 0], [-math.sin(ph), 0, math.cos(ph)]])
    rx = np.array([[1, 0, 0], [0, math.cos(th), math.sin(th)], [0, -math.sin(th), math.cos(th)]])
    return rz @ ry @ rx


def panel_normal(s):
    v = s - (s @ Y_AXIS) * Y_AXIS
    return v / np.linalg.norm(v)


def facet_term(n, s, o, coeffs, mus):
    """[n.s]+ [n.o]+ sum_m x_m beta_m(n, o, s), Beckmann lobes (eq 6), no diffuse term."""
    ns, no = float(n @ s), float(n @ o)
    if ns <= 0.0 or no <= 0.0:
        return 0.0
    h = s + o
    h = h / np.linalg.norm(h)
    c = float(n @ h)
    if c <= 0.0:
        return 0.0
    tan2 = (1.0 - c * c) / (c * c)
    d = np.exp(-tan2 / mus ** 2) / (math.pi * mus ** 2 * c ** 4)
    beta = d / (4.0 * ns * no)
    return ns * no * float(coeffs @ beta)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--axis", choices=["x", "y", "z"], required=True)
    ap.add_argument("--snr", type=float, required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--no-sigma", action="store_true")
    ap.add_argument("--perturb", action="store_true")
    a = ap.parse_args()
    os.makedirs(a.outdir, exist_ok=True)
    p_true = [0.0, 0.0, 0.0]
    p_true["xyz".index(a.axis)] = RATE_DEG_PER_FRAME

    noise_ss, pert_ss = np.random.SeedSequence(a.seed).spawn(2)
    rng_noise, rng_pert = np.random.default_rng(noise_ss), np.random.default_rng(pert_ss)

    # perturbations (always drawn, applied only with --perturb, so the streams do not depend on it)
    def signed(lo, hi, n=None):
        return rng_pert.choice([-1.0, 1.0], size=n) * rng_pert.uniform(lo, hi, size=n)
    mu_body_f = 1.0 + signed(0.05, 0.10, len(MU))
    mu_panel_f = 1.0 + signed(0.05, 0.10, len(MU))
    area_body_f = 1.0 + float(signed(0.03, 0.05))
    area_panel_f = 1.0 + float(signed(0.03, 0.05))
    off_az = float(rng_pert.uniform(0.0, 2.0 * math.pi))
    if not a.perturb:
        mu_body_f = np.ones(len(MU))
        mu_panel_f = np.ones(len(MU))
        area_body_f = area_panel_f = 1.0

    ra = solve_sun_ra()
    sun_nom = sun_inertial(ra)
    sun_true = sun_nom
    if a.perturb:
        e1 = np.cross(sun_nom, [0.0, 0.0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(sun_nom, e1)
        axis = math.cos(off_az) * e1 + math.sin(off_az) * e2
        th = math.radians(SUN_OFFSET_DEG)
        sun_true = (sun_nom * math.cos(th) + np.cross(axis, sun_nom) * math.sin(th)
                    + axis * (axis @ sun_nom) * (1 - math.cos(th)))
    dt0 = stable_start(sun_nom)
    dt_stable = -dt0 / STABLE_SAMPLES

    samples = []  # (window, frame, t_s since stable start, dt from motion start)
    for i in range(STABLE_SAMPLES):
        samples.append(("stable", i, i * dt_stable, dt0 + i * dt_stable))
    for k in range(MOTION_FRAMES):
        samples.append(("motion", k, -dt0 + k * FRAME_INTERVAL_S, k * FRAME_INTERVAL_S))

    a_ap = math.pi * PUPIL_D_M ** 2 / 4.0
    mus_b, mus_p = MU * mu_body_f, MU * mu_panel_f
    rows, clean = [], np.zeros((len(samples), len(BANDS_NM)))
    for j, (win, frame, t_s, dt) in enumerate(samples):
        s_nom, o, rng_m = geometry(dt, sun_nom)
        s_tru, _, _ = geometry(dt, sun_true)
        n_p = panel_normal(s_tru)
        if win == "motion":
            r = rot_verbatim(p_true, frame)
            s_r, o_r = r @ s_tru, r @ o
        else:
            s_r, o_r = s_tru, o
        for b, lam in enumerate(BANDS_NM):
            cb = BODY_650 * body_reflectance(lam) * area_body_f
            cp = PANEL_650 * panel_reflectance(lam) * area_panel_f
            q = facet_term(N_BODY, s_r, o_r, cb, mus_b) + facet_term(n_p, s_r, o_r, cp, mus_p)
            clean[j, b] = e_sun(lam) * a_ap / rng_m ** 2 * q * BAND_WIDTH_NM
        rows.append((win, frame, t_s, s_nom, o, rng_m))

    sigma = np.zeros_like(clean)
    sig_json = {}
    for win in ("stable", "motion"):
        m = np.array([r[0] == win for r in rows])
        sw = clean[m].mean(axis=0) / a.snr if math.isfinite(a.snr) else np.zeros(len(BANDS_NM))
        sigma[m] = sw
        sig_json[win] = {str(int(l)): float(v) for l, v in zip(BANDS_NM, sw)}
    flux = clean + rng_noise.standard_normal(clean.shape) * sigma

    order = list(range(len(BANDS_NM)))[::-1]
    head = ["r_m", "segment", "ox", "oy", "oz", "time_s", "frame", "sz", "sy", "sx"]
    for b in order:
        head.append("flux%d" % BANDS_NM[b])
        if not a.no_sigma:
            head.append("err_%d" % BANDS_NM[b])
    lines = ["# written by tests/data/inversion-other/sim_spectral.py (an independent simulator)",
             "# axis=%s snr=%s seed=%d perturb=%s sigma_columns=%s" % (
                 a.axis, a.snr, a.seed, a.perturb, not a.no_sigma),
             "# truth_rate_deg_per_frame = %r,%r,%r" % tuple(p_true),
             ",".join(head)]
    for j, (win, frame, t_s, s, o, rng_m) in enumerate(rows):
        vals = ["%.6f" % rng_m, win, "%.15f" % o[0], "%.15f" % o[1], "%.15f" % o[2], "%.6f" % t_s,
                "%d" % frame, "%.15f" % s[2], "%.15f" % s[1], "%.15f" % s[0]]
        for b in order:
            vals.append("%.9e" % flux[j, b])
            if not a.no_sigma:
                vals.append("%.9e" % sigma[j, b])
        lines.append(",".join(vals))
    with open(os.path.join(a.outdir, "observations.csv"), "w") as f:
        f.write("\n".join(lines) + "\n")

    s0, o0, r0 = geometry(0.0, sun_nom)
    truth = {
        "truth_rate_deg_per_frame": p_true,
        "convention": "verbatim eq (17): R = R_Z(w_z t) R_Y(w_y t) R_X(w_x t), s' = R s; glint's "
                      "default attitude = \"verbatim\", so this is the rate glint reports",
        "mirror_deg_per_frame": [-p_true[0], p_true[1], -p_true[2]],
        "axis": a.axis, "snr": a.snr, "seed": a.seed, "perturb": a.perturb,
        "sigma_columns": not a.no_sigma,
        "noise": "Gaussian, sigma = mean over the window of the noise-free band flux / SNR, per band and window",
        "sigma_w": sig_json,
        "bands_nm": BANDS_NM, "band_width_nm": BAND_WIDTH_NM,
        "stable_samples": STABLE_SAMPLES, "stable_interval_s": dt_stable,
        "motion_frames": MOTION_FRAMES, "frame_interval_s": FRAME_INTERVAL_S,
        "sun_ra_deg": ra, "sun_dec_deg": SUN_DEC_DEG,
        "phase_at_motion_start_deg": phase_deg(s0, o0), "range_at_motion_start_m": r0,
        "stable_start_s_before_motion": -dt0,
        "perturbations": {
            "lobe_mu_factor_body": mu_body_f.tolist(),
            "lobe_mu_factor_panel": mu_panel_f.tolist(),
            "area_factor_body": area_body_f, "area_factor_panel": area_panel_f,
            "sun_offset_deg": SUN_OFFSET_DEG if a.perturb else 0.0,
            "sun_offset_azimuth_rad": off_az if a.perturb else None,
            "sun_true_inertial": sun_true.tolist(), "sun_nominal_inertial": sun_nom.tolist(),
        },
    }
    with open(os.path.join(a.outdir, "TRUTH.json"), "w") as f:
        json.dump(truth, f, indent=1)


if __name__ == "__main__":
    main()
