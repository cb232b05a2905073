#!/usr/bin/env python3
"""An independent fisheye Earth image renderer (standard library + numpy), written to check
`glint tool earth` ([003]) on frames glint did not make.

It shares no code with glint and is built from the geometry alone:

  Earth      a sphere of radius R = 6378.137 km (WGS 84 equatorial; glint's own model uses
             6371 km) seen from altitude h = 950 km. The bright disk is every direction u with
             u.e >= cos(rho), rho = asin((R + H)/(R + h)), e the unit vector to the Earth
             centre and H the limb-height offset (--limb-km, default 0).
  attitude   the optical axis Z_S is tilted by beta from nadir about the sensor's Y axis:
             e = (sin beta, 0, cos beta) in the sensor frame. glint's tilt is
             atan2(n_x, n_z) of the ring normal oriented to the nadir side (math.md 4.4), so a
             positive beta gives a positive tilt_deg; checked on its output (beta = +10 and
             -10 read tilt_deg = +9.99 and -10.00). In the image the nadir side is to the right
             (+X, growing column) of the principal point.
  pixels     X is the column, Y the row, both 0-based with the first pixel's centre at (0, 0);
             dx = X - cx, dy = Y - cy, phi = atan2(dy, dx), and the direction is
             (sin t cos phi, sin t sin phi, cos t), as glint's eqs (6)-(9).
  lens       Kannala-Brandt (OpenCV fisheye): r = f t_d, t_d = t (1 + k1 t^2 + k2 t^4 + k3 t^6
             + k4 t^8); k = 0 (default) is the ideal equidistant lens r = f t. The field stops
             at t_max = 90 deg: the lens image circle has the radius f t_d(90 deg), and the
             detector reads 0 outside it. f = 255 / (pi/2) = 162.338 px/rad, so for the ideal
             lens the circle's radius is 255 px; the principal point is (255.5, 255.5) of a
             512 x 512 frame.
  rendering  each pixel is sampled 4 x 4. The scene (Earth 200 DN, space 12 DN, 8-bit units)
             is blurred on the subpixel grid by a separable Gaussian PSF of sigma = 1 px, then
             cut by the image circle on the same subpixel grid (the field stop follows the
             blur), then the 16 subpixels are averaged (so the circle's edge pixels are partly
             lit). Pixels with any part inside the circle get Gaussian read noise (1 DN), are
             rounded and clipped; pixels wholly outside read exactly 0.
  output     binary PGM, 8-bit (P5, maxval 255; the default) or 16-bit (--bits 16, big-endian,
             maxval 65535, levels x 257), which `glint tool earth` reads. Frame i of a run has
             the noise seed N + i.

It writes, into OUTDIR:

  <lens>-b<beta>[-limb<H>].pgm   one frame per beta; <lens> is "ideal" (k = 0) or "kb"
  TRUTH.csv                      file, beta_deg, f_px, cx, cy, altitude_km, k1, k2, k3, k4,
                                 limb_km, seed (rewritten by every run)

Usage: sim_fisheye.py OUTDIR [--beta-deg B ...] [--k1 K] [--k2 K] [--k3 K] [--k4 K]
                             [--limb-km H] [--seed N] [--bits 8|16] [--altitude-km A]
                             [--radius-km R]
"""
import argparse
import math
import os

import numpy as np

WIDTH = HEIGHT = 512
CX = CY = 255.5
THETA_MAX = math.pi / 2
F_PX = 255.0 / THETA_MAX      # the ideal lens puts theta = 90 deg at r = 255 px
SS = 4                        # subpixels per pixel side
PSF_SIGMA_PX = 1.0
EARTH_DN = 200.0              # 8-bit units
SPACE_DN = 12.0
NOISE_DN = 1.0
R_EARTH_KM = 6378.137
ALTITUDE_KM = 950.0


def theta_d(t, k):
    t2 = t * t
    return t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))


def dtheta_d(t, k):
    t2 = t * t
    return 1.0 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])))


def undistort(td, k, t_hi):
    """theta from theta_d by Newton's method (t_d(t) is checked monotone on [0, t_hi])."""
    t = np.minimum(td, t_hi)
    if not any(k):
        return t
    for _ in range(30):
        t = np.clip(t - (theta_d(t, k) - td) / dtheta_d(t, k), 0.0, t_hi)
    return t


def gaussian_blur(img, sigma):
    """Separable Gaussian, edges extended."""
    rad = int(math.ceil(4 * sigma))
    x = np.arange(-rad, rad + 1)
    w = np.exp(-0.5 * (x / sigma) ** 2)
    w /= w.sum()
    for axis in (0, 1):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (rad, rad)
        p = np.pad(img, pad, mode="edge")
        n = img.shape[axis]
        out = np.zeros_like(img)
        for i, wi in enumerate(w):
            sl = [slice(None), slice(None)]
            sl[axis] = slice(i, i + n)
            out += wi * p[tuple(sl)]
        img = out
    return img


def render(beta_deg, k, limb_km, seed, altitude_km, radius_km):
    # the lens must map theta monotonically over the field and a margin beyond it
    t_hi = THETA_MAX + 0.6
    ts = np.linspace(0.0, t_hi, 2001)
    if np.any(dtheta_d(ts, k) <= 0):
        raise SystemExit("lens: theta_d is not monotone up to %.1f deg" % math.degrees(t_hi))
    r_circle = F_PX * theta_d(THETA_MAX, k)

    off = (np.arange(SS) + 0.5) / SS - 0.5
    xs = (np.arange(WIDTH)[:, None] + off[None, :]).ravel() - CX
    ys = (np.arange(HEIGHT)[:, None] + off[None, :]).ravel() - CY
    dx, dy = np.meshgrid(xs, ys)          # rows are Y, columns X
    r = np.hypot(dx, dy)
    t = undistort(r / F_PX, k, t_hi)
    rs = np.where(r > 0, r, 1.0)
    st = np.sin(t)
    ux, uy, uz = st * dx / rs, st * dy / rs, np.cos(t)

    b = math.radians(beta_deg)
    e = (math.sin(b), 0.0, math.cos(b))
    cos_rho = math.cos(math.asin((radius_km + limb_km) / (radius_km + altitude_km)))
    earth = ux * e[0] + uy * e[1] + uz * e[2] >= cos_rho
    scene = np.where(earth, EARTH_DN, SPACE_DN)
    scene = gaussian_blur(scene, PSF_SIGMA_PX * SS)
    inside = r <= r_circle
    img = (scene * inside).reshape(HEIGHT, SS, WIDTH, SS).mean(axis=(1, 3))
    cover = inside.reshape(HEIGHT, SS, WIDTH, SS).any(axis=(1, 3))
    rng = np.random.default_rng(seed)
    img = img + NOISE_DN * rng.standard_normal(img.shape)
    img[~cover] = 0.0
    return img


def write_pgm(path, img, bits):
    if bits == 8:
        a = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        maxval = 255
    else:
        a = np.clip(np.rint(img * 257.0), 0, 65535).astype(">u2")
        maxval = 65535
    with open(path, "wb") as f:
        f.write(b"P5\n%d %d\n%d\n" % (WIDTH, HEIGHT, maxval))
        f.write(a.tobytes())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("--beta-deg", type=float, nargs="+", default=[10.0])
    for i in range(1, 5):
        ap.add_argument("--k%d" % i, type=float, default=0.0)
    ap.add_argument("--limb-km", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=2003)
    ap.add_argument("--bits", type=int, choices=(8, 16), default=8)
    ap.add_argument("--altitude-km", type=float, default=ALTITUDE_KM)
    ap.add_argument("--radius-km", type=float, default=R_EARTH_KM)
    a = ap.parse_args()
    k = (a.k1, a.k2, a.k3, a.k4)
    os.makedirs(a.outdir, exist_ok=True)
    lens = "ideal" if not any(k) else "kb"
    rows = []
    for i, beta in enumerate(a.beta_deg):
        name = "%s-b%g%s.pgm" % (lens, beta, "-limb%g" % a.limb_km if a.limb_km else "")
        seed = a.seed + i
        img = render(beta, k, a.limb_km, seed, a.altitude_km, a.radius_km)
        write_pgm(os.path.join(a.outdir, name), img, a.bits)
        rows.append("%s,%g,%.9f,%g,%g,%g,%g,%g,%g,%g,%g,%d"
                    % (name, beta, F_PX, CX, CY, a.altitude_km, *k, a.limb_km, seed))
    with open(os.path.join(a.outdir, "TRUTH.csv"), "w") as f:
        f.write("file,beta_deg,f_px,cx,cy,altitude_km,k1,k2,k3,k4,limb_km,seed\n")
        f.write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
