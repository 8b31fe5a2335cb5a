#!/usr/bin/python3
"""Ground control residuals of a COLMAP model from control points picked in photos.

COLMAP 3.8 cannot use control points picked in photos: its model_aligner only
fits a similarity between the model's camera centres and reference positions
of those centres (EXIF GNSS or a text list). This script does what a COLMAP
user has to do by hand (issue 34, COLMAP #767/#152):

  1. reads COLMAP's TXT model (cameras.txt, images.txt; model_converter
     --output_type TXT) and ODM's gcp_list.txt (first line the CRS; then
     geo_x geo_y geo_z im_x im_y image_name [gcp_name]);
  2. triangulates every GCP picked in >= 2 registered photos from the
     registered poses (pick undistorted with the model's camera, linear
     triangulation, then Gauss-Newton on the reprojection error);
  3. fits a 3-D similarity (Umeyama, numpy) from the model to the GCP
     coordinates and prints, per GCP, the residual in metres (all GCPs as
     control) and the leave-one-out residual (the GCP as a check point, the
     similarity fitted on the others), with RMS over the points.

With --write-ref FILE it also writes, for every registered photo, its camera
centre transformed by the fitted similarity ("NAME X Y Z"), the reference a
COLMAP model_aligner --ref_is_gps 0 run can read. With --no-fit the model is
taken as already in the GCP frame (e.g. after model_aligner) and the residuals
are those of the model as it stands.

Numpy only. Pixel coordinates: COLMAP puts the centre of the top-left pixel at
(0.5, 0.5); ODM's picks are taken as the same convention (a 0.5 px difference
is below the picking precision).
"""
import argparse
import math
import sys

import numpy as np


def read_cameras(path):
    cams = {}
    with open(path) as f:
        for line in f:
            if not line.strip() or line.startswith('#'):
                continue
            p = line.split()
            cams[int(p[0])] = (p[1], int(p[2]), int(p[3]), [float(v) for v in p[4:]])
    return cams


def read_images(path):
    """name -> (R world->camera, t, camera_id)"""
    imgs = {}
    with open(path) as f:
        lines = [l for l in f if not l.startswith('#')]
    # image lines alternate with their 2-D point lines
    for i in range(0, len(lines) - 1, 2):
        p = lines[i].split()
        if len(p) < 10:
            continue
        qw, qx, qy, qz, tx, ty, tz = (float(v) for v in p[1:8])
        imgs[' '.join(p[9:])] = (quat_to_r(qw, qx, qy, qz), np.array([tx, ty, tz]), int(p[8]))
    return imgs


def quat_to_r(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def camera_split(model, params):
    """(f_x, f_y, c_x, c_y, distortion function on normalized coords)"""
    if model == 'SIMPLE_PINHOLE':
        f, cx, cy = params
        return f, f, cx, cy, lambda u, v: (u, v)
    if model == 'PINHOLE':
        fx, fy, cx, cy = params
        return fx, fy, cx, cy, lambda u, v: (u, v)
    if model == 'SIMPLE_RADIAL':
        f, cx, cy, k = params
        return f, f, cx, cy, lambda u, v: (u * (1 + k * (u * u + v * v)), v * (1 + k * (u * u + v * v)))
    if model == 'RADIAL':
        f, cx, cy, k1, k2 = params

        def d(u, v):
            r2 = u * u + v * v
            s = 1 + k1 * r2 + k2 * r2 * r2
            return u * s, v * s
        return f, f, cx, cy, d
    if model == 'OPENCV':
        fx, fy, cx, cy, k1, k2, p1, p2 = params

        def d(u, v):
            r2 = u * u + v * v
            s = 1 + k1 * r2 + k2 * r2 * r2
            return (u * s + 2 * p1 * u * v + p2 * (r2 + 2 * u * u),
                    v * s + p1 * (r2 + 2 * v * v) + 2 * p2 * u * v)
        return fx, fy, cx, cy, d
    raise ValueError(f'camera model {model} not supported by this script')


def project(cam, R, t, X):
    fx, fy, cx, cy, dist = camera_split(cam[0], cam[3])
    Xc = R @ X + t
    u, v = Xc[0] / Xc[2], Xc[1] / Xc[2]
    ud, vd = dist(u, v)
    return np.array([fx * ud + cx, fy * vd + cy]), Xc[2]


def undistort(cam, px):
    fx, fy, cx, cy, dist = camera_split(cam[0], cam[3])
    ud, vd = (px[0] - cx) / fx, (px[1] - cy) / fy
    u, v = ud, vd
    for _ in range(100):  # fixed point; converges for the small distortion of these models
        du, dv = dist(u, v)
        u, v = u - (du - ud), v - (dv - vd)
    return u, v


def triangulate(obs, cams, imgs):
    """obs: list of (image name, pixel). Returns X (model frame) and per-pick reprojection errors."""
    A = []
    for name, px in obs:
        R, t, cid = imgs[name]
        u, v = undistort(cams[cid], px)
        P = np.hstack([R, t[:, None]])
        A.append(u * P[2] - P[0])
        A.append(v * P[2] - P[1])
    _, _, vt = np.linalg.svd(np.array(A))
    X = vt[-1, :3] / vt[-1, 3]
    for _ in range(20):  # Gauss-Newton on the pixel reprojection error
        J, r = [], []
        for name, px in obs:
            R, t, cid = imgs[name]
            p0, _ = project(cams[cid], R, t, X)
            r.extend(p0 - px)
            h = 1e-6 * max(1.0, np.linalg.norm(X))
            cols = []
            for k in range(3):
                dX = np.zeros(3)
                dX[k] = h
                cols.append((project(cams[cid], R, t, X + dX)[0] - p0) / h)
            J.extend(np.array(cols).T)
        J, r = np.array(J), np.array(r)
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        X = X + step
        if np.linalg.norm(step) < 1e-12 * max(1.0, np.linalg.norm(X)):
            break
    errs, depths, centres = [], [], []
    for name, px in obs:
        R, t, cid = imgs[name]
        p, z = project(cams[cid], R, t, X)
        errs.append(float(np.linalg.norm(p - px)))
        depths.append(z)
        centres.append(-R.T @ t)
    # largest angle between two rays (degrees): the geometry of the intersection
    ang = 0.0
    for i in range(len(centres)):
        for j in range(i + 1, len(centres)):
            a, b = centres[i] - X, centres[j] - X
            c = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
            ang = max(ang, math.degrees(math.acos(max(-1.0, min(1.0, c)))))
    return X, errs, min(depths), ang


def triangulate_robust(obs, cams, imgs, max_px):
    """Triangulates; while a pick is off by more than max_px (or the point falls behind a
    camera) and >= 3 picks remain, drops the pick whose removal fits the rest best.
    Returns X, errors of the kept picks, min depth, ray angle, kept obs, dropped [(image, px off)]."""
    X, errs, zmin, ang = triangulate(obs, cams, imgs)
    dropped = []
    while (max(errs) > max_px or zmin <= 0) and len(obs) >= 3:
        best = None
        for i in range(len(obs)):
            rest = obs[:i] + obs[i + 1:]
            Xi, ei, zi, ai = triangulate(rest, cams, imgs)
            score = max(ei) if zi > 0 else float('inf')
            if best is None or score < best[0]:
                best = (score, i, Xi, ei, zi, ai)
        _, i, Xi, ei, zi, ai = best
        R, t, cid = imgs[obs[i][0]]
        off = float(np.linalg.norm(project(cams[cid], R, t, Xi)[0] - obs[i][1])) if zi > 0 else float('nan')
        dropped.append((obs[i][0], off))
        obs = obs[:i] + obs[i + 1:]
        X, errs, zmin, ang = Xi, ei, zi, ai
    return X, errs, zmin, ang, obs, dropped


def umeyama(src, dst):
    """s, R, t with dst ~ s R src + t (least squares)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    cov = b.T @ a / len(src)
    U, S, Vt = np.linalg.svd(cov)
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    R = U @ D @ Vt
    var = (a ** 2).sum() / len(src)
    s = np.trace(np.diag(S) @ D) / var
    return s, R, md - s * R @ ms


def rms(v):
    v = np.asarray(v, dtype=float)
    return float(np.sqrt((v ** 2).mean())) if len(v) else float('nan')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--model', required=True, help='COLMAP TXT model folder (cameras.txt, images.txt)')
    ap.add_argument('--gcp', required=True, help="ODM gcp_list.txt")
    ap.add_argument('--write-ref', help='write NAME X Y Z of every registered camera centre in the GCP frame')
    ap.add_argument('--no-fit', action='store_true', help='model already in the GCP frame: no similarity')
    ap.add_argument('--max-pick-px', type=float, default=5.0,
                    help='a pick further than this from the triangulated point is dropped while >= 2 remain (default 5)')
    a = ap.parse_args()

    cams = read_cameras(f'{a.model}/cameras.txt')
    imgs = read_images(f'{a.model}/images.txt')
    with open(a.gcp) as f:
        rows = f.read().splitlines()
    crs = rows[0].strip()
    gcps = {}  # name -> (xyz, [(image, px, line no)])
    missing = []
    for ln, row in enumerate(rows[1:], start=2):
        p = row.split()
        if not p or p[0].startswith('#'):
            continue
        if len(p) < 6:
            print(f'{a.gcp}:{ln}: fewer than 6 fields, skipped', file=sys.stderr)
            continue
        xyz = np.array([float(v) for v in p[0:3]])
        px = np.array([float(p[3]), float(p[4])])
        img = p[5]
        name = p[6] if len(p) > 6 else f'{p[0]}_{p[1]}_{p[2]}'
        g = gcps.setdefault(name, (xyz, []))
        if np.linalg.norm(g[0] - xyz) > 1e-6:
            print(f'{a.gcp}:{ln}: {name} has other coordinates than on its first line; first kept', file=sys.stderr)
        if img not in imgs:
            missing.append(f'{a.gcp}:{ln}: {name} picked in {img}, which COLMAP did not register')
            continue
        g[1].append((img, px))

    print(f'model: {a.model}: {len(imgs)} registered photos, camera {", ".join(c[0] for c in cams.values())}')
    print(f'gcp: {a.gcp}: {sum(len(v[1]) for v in gcps.values())} picks in registered photos of {len(gcps)} points; CRS "{crs}"')
    for m in missing:
        print(m)
    # two GCPs picked at (nearly) the same pixel of one photo: one of the labels is wrong
    picks = [(img, px, name) for name, (_, obs) in gcps.items() for img, px in obs]
    for i in range(len(picks)):
        for j in range(i + 1, len(picks)):
            if picks[i][0] == picks[j][0] and picks[i][2] != picks[j][2] \
                    and np.linalg.norm(picks[i][1] - picks[j][1]) < 10:
                print(f'warning: {picks[i][2]} and {picks[j][2]} are picked {np.linalg.norm(picks[i][1] - picks[j][1]):.1f} px '
                      f'apart in {picks[i][0]}: one of the two labels is wrong')
    zs = {float(v[0][2]) for v in gcps.values()}
    if zs == {0.0}:
        print('note: every GCP height in the file is 0 (not surveyed): vertical residuals measure the '
              'terrain relief and the tilt of the fit, not height accuracy')

    names, model_pts, geo_pts = [], [], []
    info = {}
    for name in sorted(gcps):
        xyz, obs = gcps[name]
        if len(obs) < 2:
            print(f'{name}: picked in {len(obs)} registered photo(s): cannot be triangulated, left out')
            continue
        X, errs, zmin, ang, kept, dropped = triangulate_robust(obs, cams, imgs, a.max_pick_px)
        for img, off in dropped:
            print(f'{name}: pick in {img} is {off:.0f} px from the point the other {len(kept)} picks give: dropped')
        if zmin <= 0 or max(errs) > a.max_pick_px:
            print(f'{name}: its {len(kept)} picks do not meet in one point '
                  f'({"behind a camera" if zmin <= 0 else f"{max(errs):.0f} px off"}): left out')
            continue
        obs = kept
        names.append(name)
        model_pts.append(X)
        geo_pts.append(xyz)
        info[name] = (len(obs), rms(errs), ang)
    model_pts, geo_pts = np.array(model_pts), np.array(geo_pts)
    if len(names) < 3:
        print(f'only {len(names)} GCPs triangulated: a similarity needs 3', file=sys.stderr)
        return 1

    if a.no_fit:
        s, R, t = 1.0, np.eye(3), np.zeros(3)
    else:
        s, R, t = umeyama(model_pts, geo_pts)
    fitted = (s * (R @ model_pts.T)).T + t
    res = fitted - geo_pts
    loo = np.full_like(res, np.nan)
    if not a.no_fit and len(names) >= 4:
        for i in range(len(names)):
            keep = [j for j in range(len(names)) if j != i]
            si, Ri, ti = umeyama(model_pts[keep], geo_pts[keep])
            loo[i] = si * Ri @ model_pts[i] + ti - geo_pts[i]

    if not a.no_fit:
        ypr = np.degrees([math.atan2(R[1, 0], R[0, 0]), -math.asin(max(-1, min(1, R[2, 0]))),
                          math.atan2(R[2, 1], R[2, 2])])
        print(f'similarity model -> GCP frame: scale {s:.6g} m per model unit, '
              f'rotation z/y/x {ypr[0]:.2f}/{ypr[1]:.2f}/{ypr[2]:.2f} deg, fitted on {len(names)} GCPs')
    print()
    hdr = (f'{"gcp":8s} {"picks":>5s} {"reproj px":>9s} {"ray deg":>7s} | {"resid dx" if a.no_fit else "control dx":>10s} {"dy":>7s} {"dz":>7s} {"3-D m":>7s}'
           + ('' if a.no_fit else f' | {"check dx":>8s} {"dy":>7s} {"dz":>7s} {"3-D m":>7s}'))
    print(hdr)
    for i, name in enumerate(names):
        n, rp, ang = info[name]
        line = (f'{name:8s} {n:5d} {rp:9.2f} {ang:7.1f} | {res[i, 0]:10.3f} {res[i, 1]:7.3f} {res[i, 2]:7.3f} '
                f'{np.linalg.norm(res[i]):7.3f}')
        if not a.no_fit:
            line += (f' | {loo[i, 0]:8.3f} {loo[i, 1]:7.3f} {loo[i, 2]:7.3f} {np.linalg.norm(loo[i]):7.3f}')
        print(line)
    print()
    label = 'as it stands (no fit)' if a.no_fit else 'control (all GCPs in the fit)'
    print(f'{label}: RMS horizontal {rms(np.linalg.norm(res[:, :2], axis=1)):.3f} m, '
          f'vertical {rms(res[:, 2]):.3f} m, 3-D {rms(np.linalg.norm(res, axis=1)):.3f} m over {len(names)} GCPs')
    if not a.no_fit and len(names) >= 4:
        print(f'check (leave one out): RMS horizontal {rms(np.linalg.norm(loo[:, :2], axis=1)):.3f} m, '
              f'vertical {rms(loo[:, 2]):.3f} m, 3-D {rms(np.linalg.norm(loo, axis=1)):.3f} m over {len(names)} GCPs')
    print(f'pick reprojection RMS over all triangulated picks: '
          f'{rms([info[n][1] for n in names for _ in range(info[n][0])]):.2f} px (per-GCP RMS weighted by picks)')

    if a.write_ref:
        with open(a.write_ref, 'w') as f:
            for name in sorted(imgs):
                Rw, tw, _ = imgs[name]
                C = -Rw.T @ tw
                Cg = s * R @ C + t
                f.write(f'{name} {Cg[0]:.4f} {Cg[1]:.4f} {Cg[2]:.4f}\n')
        print(f'wrote {len(imgs)} camera centres in the GCP frame to {a.write_ref}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
