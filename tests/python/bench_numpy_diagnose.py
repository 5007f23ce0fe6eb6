#!/usr/bin/env python3
"""NumPy/SciPy reference of `jointctl diagnose` (torque mode) for the speed comparison.

The same analysis as host-sim/analysis/src/diagnose, written the way a NumPy user would write it: read
the CSV, smooth q̇ (±5 ms), tag regimes, split into 20 interleaved blocks (6 held out, 50-sample
guards, 10 units per held-out block), refit the model's terms by least squares, search every
effect's shape on 20 000 thinned training rows (same grids and golden-section steps), fit each
candidate on ≤ 150 000 training rows, score on the held-out rows per unit and regime, test with
the same two unit t-tests, run forward selection, and compute the residual correlations. The
final fits remove the logged q̈'s white-noise variance from its normal equation (errors in
variables), as the Rust code does, and the floor margin is then 1.02.

Usage: bench_numpy_diagnose.py [--lstsq] LOG.csv MODEL.toml   (prints timings and the verdict)
  --lstsq: every grid point solved with np.linalg.lstsq on the full design (how a plain NumPy
  port would do it) instead of bordering the normal equations like the Rust code.
The model is read with tomllib; only the sections the bench model uses are supported.
"""
import math
import sys
import time
import tomllib

import numpy as np
from scipy import stats

ALPHA, MIN_GAIN = 0.05, 0.02
NAIVE = False


def smooth(x, h):
    c = np.concatenate([[0.0], np.cumsum(x)])
    i = np.arange(len(x))
    a = np.maximum(i - h, 0)
    b = np.minimum(i + h + 1, len(x))
    return (c[b] - c[a]) / (b - a)


def golden(lo, hi, iters, f):
    r = 0.5 * (math.sqrt(5) - 1)
    x1, x2 = hi - r * (hi - lo), lo + r * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(iters):
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - r * (hi - lo)
            f1 = f(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + r * (hi - lo)
            f2 = f(x2)
    return (x1, f1) if f1 <= f2 else (x2, f2)


def main(log_path, model_path):
    t0 = time.perf_counter()
    with open(log_path) as fh:
        header = fh.readline().strip().split(",")
    data = np.loadtxt(log_path, delimiter=",", skiprows=1)
    col = {n: data[:, i] for i, n in enumerate(header)}
    t_read = time.perf_counter() - t0
    t1 = time.perf_counter()
    with open(model_path, "rb") as fh:
        m = tomllib.load(fh)
    fr, w, j, off = m.get("friction", {}), m.get("weight", {}), m.get("inertia", {}).get("j", 0.0), m.get("offset", {}).get("c0", 0.0)
    a, b, c, band = fr.get("a", 0.0), fr.get("b", 0.0), fr.get("c", 0.0), fr.get("v_band", 0.01)
    amp, s, phi = w.get("amplitude", 0.0), w.get("s", 1.0), w.get("phi", 0.0)
    t, q, qdd, u = col["t"], col["q"], col["qdd"], col["u"]
    dt = float(np.median(np.diff(t[: 20001])))
    qd = smooth(col["qd"], min(int(round(0.005 / dt)), 25))
    n = len(t)
    sg = np.clip(qd / band, -1, 1)
    d = u - col["tau"]
    X = np.column_stack([qdd, qd * np.abs(qd), qd, sg, np.sin(s * q), np.cos(s * q), np.ones(n)])
    beta0 = np.array([j, a, b, c, amp * math.cos(phi), amp * math.sin(phi), off])
    y = d
    r0 = y - X @ beta0
    # regimes
    aqd = np.abs(qd)
    v95 = max(np.percentile(aqd[:: max(n // 50000, 1)], 95), 1e-6)
    v_static, v_low = max(0.02 * v95, 1e-4), 0.2 * v95
    a90 = np.percentile(np.abs(qdd)[:: max(n // 50000, 1)], 90)
    qb = np.percentile(q[:: max(n // 50000, 1)], [25, 50, 75])
    masks = [aqd < v_static, (aqd >= v_static) & (aqd < v_low), aqd >= v_low]
    half = int(np.clip(round(0.05 / dt), 2, 500))
    fast = np.nonzero(aqd >= v_low)[0]
    sgn_fast = np.sign(qd[fast])
    ch = np.nonzero(sgn_fast[1:] != sgn_fast[:-1])[0]
    rev = np.zeros(n, bool)
    for k in ch:
        lo, hi = fast[k], fast[k + 1]
        z = lo + int(np.argmax(qd[lo : hi + 1] * sgn_fast[k + 1] > 0))
        rev[max(z - half, 0) : min(z + half, n - 1) + 1] = True
    masks.append(rev)
    masks.append(np.abs(qdd) > a90)
    band_idx = np.searchsorted(qb, q, side="right")
    masks += [band_idx == k for k in range(4)]
    mid = 0.5 * (t[0] + t[-1])
    masks += [t < mid, t >= mid]
    M = np.array(masks)
    shares = (M * r0**2).sum(1) / (r0**2).sum()
    # split
    blocks = 20
    ln = -(-n // blocks)
    guard = min(ln // 10, 50)
    subs = int(np.clip(ln // 50, 2, 10))
    i = np.arange(n)
    blk, offs = i // ln, i % ln
    held = np.isin(blk % 10, [2, 5, 8])
    near = (np.isin((blk + 1) % 10, [2, 5, 8]) & (ln - offs <= guard)) | ((blk > 0) & np.isin((blk - 1) % 10, [2, 5, 8]) & (offs < guard))
    train = np.nonzero(~held & ~near)[0]
    hold = np.nonzero(held)[0]
    hb = blk[hold]
    _, hb_rank = np.unique(hb, return_inverse=True)
    unit = hb_rank * subs + np.minimum(offs[hold] * subs // ln, subs - 1)
    n_units = unit.max() + 1
    thin = lambda idx, mx: idx[:: max(-(-len(idx) // mx), 1)]
    fit_idx, grid_idx = thin(train, 150_000), thin(train, 20_000)
    floor = np.median(np.abs(r0[2:] - 2 * r0[1:-1] + r0[:-2])[:: max(n // 200000, 1)]) / (0.67448975 * math.sqrt(6))
    span_t = t[-1] - t[0]

    def target(lag, idx):
        if lag == 0:
            return y[idx]
        pos = np.maximum(idx - lag, 0.0)
        k = np.floor(pos).astype(int)
        f = pos - k
        ut = u[np.minimum(k, n - 1)] + f * (u[np.minimum(k + 1, n - 1)] - u[np.minimum(k, n - 1)])
        return y[idx] + ut - u[idx]

    def effect_cols(e, idx, base_beta=None):
        kind, p = e
        if kind == "stribeck":
            return [np.exp(-((qd[idx] / p) ** 2)) * sg[idx]]
        if kind == "asymmetric_friction":
            return [np.abs(sg[idx])]
        if kind == "load_dependent_friction":
            return [np.abs(u[idx]) * sg[idx]]
        if kind == "thermal_drift":
            tau, aa, bb, cc, mean = p
            f = aa * qd[idx] * np.abs(qd[idx]) + bb * qd[idx] + cc * sg[idx]
            return [f * (1 - np.exp(-(t[idx] - t[0]) / tau) - mean)]
        if kind == "position_ripple":
            wq = 2 * np.pi * q[idx] / p
            return [np.sin(wq), np.cos(wq)]
        if kind == "cable_spring":
            x = q[idx] - p
            return [np.where(x <= 0, 0.0, np.where(x < 0.01, x * x / 0.02, x - 0.005))]
        return []

    def design(effects, idx):
        cols = [X[idx]]
        lag = 0.0
        for e in effects:
            if e[0] == "delay":
                lag = e[1]
            else:
                cc = effect_cols(e, idx)
                if cc:
                    cols.append(np.column_stack(cc))
        return np.hstack(cols), target(lag, idx)

    cache = {}

    def rss_lstsq(effects, idx):
        """Training RSS the plain NumPy way: build the full design, np.linalg.lstsq."""
        A, yy = design(effects, idx)
        sc = np.linalg.norm(A, axis=0)
        sc[sc == 0] = 1
        coef, *_ = np.linalg.lstsq(A / sc, yy, rcond=None)
        r = yy - (A / sc) @ coef
        return float(r @ r)

    def rss(effects, idx):
        if NAIVE:
            return rss_lstsq(effects, idx)
        """Training RSS on the grid rows: the chosen effects' design is built once and bordered
        with the new effect's columns (the same normal-equation trick as the Rust code)."""
        *chosen, e = effects
        key = repr(chosen)
        if key not in cache:
            A, yy = design(chosen, idx)
            cache[key] = (A, yy, A.T @ A, A.T @ yy, yy @ yy)
        A, yy, G, bvec, yty = cache[key]
        if e[0] == "delay":
            yt = target(e[1], idx)
            G2, b2, yty2 = G, A.T @ yt, yt @ yt
        else:
            Z = np.column_stack(effect_cols(e, idx))
            AZ = A.T @ Z
            G2 = np.block([[G, AZ], [AZ.T, Z.T @ Z]])
            b2 = np.concatenate([bvec, Z.T @ yy])
            yty2 = yty
        d = np.sqrt(np.maximum(np.diag(G2), 1e-300))
        Gs = G2 / np.outer(d, d) + 1e-10 * np.eye(len(d))
        z = np.linalg.solve(Gs, b2 / d)
        return float(max(yty2 - (z / d) @ b2, 0.0))

    def score(effects, beta):
        A, yy = design(effects, hold)
        r2 = (yy - A @ beta) ** 2
        usse = np.bincount(unit, r2, n_units)
        un = np.bincount(unit, None, n_units)
        rsse = (M[:, hold] * r2).sum(1)
        return {"effects": effects, "beta": beta, "mse": r2.mean(), "usse": usse, "un": un, "rsse": rsse}

    # white noise on the logged q̈ (column 0 of X): (1.4826·median|Δq̈|)²/2, upper median as in Rust
    dq = np.abs(np.diff(qdd))
    qdd_nv = (1.4826 * np.partition(dq, len(dq) // 2)[len(dq) // 2]) ** 2 / 2
    at_floor_k = 1.02 if qdd_nv > 0 else 1.05

    def fit_score(effects):
        A, yy = design(effects, fit_idx)
        G, bv = A.T @ A, A.T @ yy
        noise = len(fit_idx) * qdd_nv
        if 0 < noise < 0.5 * G[0, 0]:
            G[0, 0] -= noise
        dg = np.sqrt(np.maximum(np.diag(G), 1e-300))
        z = np.linalg.solve(G / np.outer(dg, dg) + 1e-12 * np.eye(len(dg)), bv / dg)
        return score(effects, z / dg)

    def compare(ref, cand):
        ok = (ref["un"] > 0) & (ref["usse"] > 0) & (cand["usse"] > 0)
        logs = np.log(ref["usse"][ok] / cand["usse"][ok])
        diffs = (ref["usse"][ok] - cand["usse"][ok]) / ref["un"][ok]
        ps = []
        for v in (logs, diffs):
            res = stats.ttest_1samp(v, 0.0, alternative="greater")
            ps.append(res.pvalue if np.isfinite(res.pvalue) else 1.0)
        gain = 1 - cand["mse"] / ref["mse"]
        return min(1.0, 2 * min(ps)), gain

    def log_search(lo, hi, k, make, chosen):
        pts = np.linspace(math.log(lo), math.log(hi), k)
        vals = [rss(chosen + [make(math.exp(x))], grid_idx) for x in pts]
        bi = int(np.argmin(vals))
        x, _ = golden(pts[max(bi - 1, 0)], pts[min(bi + 1, k - 1)], 18, lambda x: rss(chosen + [make(math.exp(x))], grid_idx))
        return make(math.exp(x))

    def search(kind, chosen):
        if kind == "stribeck":
            v95g = max(np.percentile(aqd[grid_idx], 95), 1e-3)
            return log_search(min(max(1.5 * band, 1e-4), 0.05 * v95g), 0.6 * v95g, 24, lambda v: ("stribeck", v), chosen)
        if kind in ("asymmetric_friction", "load_dependent_friction"):
            return (kind, None)
        if kind == "thermal_drift":
            A, yy = design(chosen, grid_idx)
            coef, *_ = np.linalg.lstsq(A, yy, rcond=None)
            aa, bb, cc = coef[1], coef[2], coef[3]

            def mk(tau):
                mean = float(np.mean(1 - np.exp(-(t[grid_idx] - t[0]) / tau)))
                return ("thermal_drift", (tau, aa, bb, cc, mean))

            return log_search(0.05 * span_t, 20 * span_t, 12, mk, chosen)
        if kind == "position_ripple":
            A, yy = design(chosen, grid_idx)
            coef, *_ = np.linalg.lstsq(A, yy, rcond=None)
            res = yy - A @ coef
            qg = q[grid_idx]
            qmin, qmax = qg.min(), qg.max()
            rng = qmax - qmin
            nb = 2048
            bi = np.minimum(((qg - qmin) / rng * nb).astype(int), nb - 1)
            ssum = np.bincount(bi, res, nb)
            cnt = np.bincount(bi, None, nb)
            okb = cnt > 0
            centres = qmin + (np.arange(nb)[okb] + 0.5) * rng / nb
            mean = ssum[okb] / cnt[okb]
            p_min, p_max = max(8 * rng / nb, 2e-3), rng / 3
            df = 0.25 / rng
            fr_ = np.arange(1 / p_max, 1 / p_min + df, df)
            ph = 2 * np.pi * np.outer(fr_, centres)
            wts = cnt[okb] * mean
            pw = ((np.sin(ph) @ wts) ** 2 + (np.cos(ph) @ wts) ** 2) / cnt.sum()
            pk = np.nonzero((pw[1:-1] >= pw[:-2]) & (pw[1:-1] >= pw[2:]))[0] + 1
            pk = pk[np.argsort(-pw[pk])][:3]
            best = None
            for k in pk:
                fx, r = golden(fr_[k] - df, fr_[k] + df, 16, lambda f: rss(chosen + [("position_ripple", 1 / f)], grid_idx))
                if best is None or r < best[1]:
                    best = (fx, r)
            return ("position_ripple", 1 / best[0])
        if kind == "cable_spring":
            qs = np.sort(q[grid_idx])
            pts = qs[np.round((len(qs) - 1) * (0.02 + 0.9 * np.arange(40) / 39)).astype(int)]
            vals = [rss(chosen + [("cable_spring", e)], grid_idx) for e in pts]
            bi = int(np.argmin(vals))
            e, _ = golden(pts[max(bi - 1, 0)], pts[min(bi + 1, 39)], 20, lambda e: rss(chosen + [("cable_spring", e)], grid_idx))
            return ("cable_spring", e)
        if kind == "delay":
            mx = int(np.clip(round(0.1 / dt), 3, 200))
            vals = [rss(chosen + [("delay", float(l))], grid_idx) for l in range(mx + 1)]
            bi = 1 + int(np.argmin(vals[1:]))
            lag = float(bi)
            if bi < mx:
                y0, y1, y2 = vals[bi - 1], vals[bi], vals[bi + 1]
                den = y0 - 2 * y1 + y2
                lag += float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den > 0 else 0.0
            return ("delay", lag)
        return None

    kinds = ["stribeck", "asymmetric_friction", "load_dependent_friction", "thermal_drift", "position_ripple", "cable_spring", "delay"]
    alpha_each = ALPHA / (len(kinds) + 3)
    m0 = score([], beta0)
    refit = fit_score([])
    at_floor = math.sqrt(m0["mse"]) <= at_floor_k * floor
    p, g = compare(m0, refit)
    refit_sig = (not at_floor) and p < alpha_each and g >= MIN_GAIN
    cands = []
    for k in kinds:
        e = search(k, [])
        sc = fit_score([e])
        p, g = compare(refit, sc)
        cands.append((k, sc, p, (not at_floor) and p < alpha_each and g >= MIN_GAIN))
    chosen = []
    sig = [cd for cd in cands if cd[3]]
    if sig:
        cur = min(sig, key=lambda cd: cd[1]["mse"])
        chosen.append(cur)
        while len(chosen) < 3 and math.sqrt(cur[1]["mse"]) > at_floor_k * floor:
            effs = cur[1]["effects"]
            nxt = []
            A, yy = design(effs, grid_idx)
            cur_rss = float(np.sum((yy - A @ np.linalg.lstsq(A, yy, rcond=None)[0]) ** 2))
            for k in kinds:
                if any(e[0] == k for e in effs):
                    continue
                e = search(k, effs)
                if rss(effs + [e], grid_idx) > (1 - 0.5 * MIN_GAIN) * cur_rss:
                    continue  # same pruning as the Rust code: too little training gain
                sc = fit_score(effs + [e])
                p, g = compare(cur[1], sc)
                if p < alpha_each and g >= MIN_GAIN:
                    nxt.append((k, sc, p, True))
            if not nxt:
                break
            cur = min(nxt, key=lambda cd: cd[1]["mse"])
            chosen.append(cur)
    # resid evidence on the first ≤50 000 held-out samples
    hidx = hold[:50_000]
    fin = chosen[-1][1] if chosen else (refit if refit_sig else m0)
    A, yy = design(fin["effects"], hidx)
    ra = yy - A @ fin["beta"]
    rb = r0[hidx]
    lag = int(np.clip(round(0.1 / dt), 10, 100))

    def xc(r, x, auto):
        r = r - r.mean()
        x = x - x.mean()
        den = r.std() * x.std() * len(r)
        lags = range(0 if auto else -lag, lag + 1)
        return np.array([(r[max(L, 0) : len(r) + min(L, 0)] @ x[max(-L, 0) : len(x) - max(L, 0)]) / den for L in lags])

    ev = [xc(rb, rb, True), xc(ra, ra, True), xc(rb, qd[hidx], False), xc(rb, u[hidx], False), xc(ra, qd[hidx], False), xc(ra, u[hidx], False)]
    t_diag = time.perf_counter() - t1
    verdict = [cd[0] for cd in chosen] or (["parameters"] if refit_sig else ["none"])
    total = t_read + t_diag
    print(f"numpy diagnose {n} samples: read {t_read:.3f} s + diagnose {t_diag:.3f} s = {total:.3f} s; verdict {' -> '.join(verdict)}; "
          f"held-out RMSE {math.sqrt(m0['mse']):.4f} -> {math.sqrt(fin['mse']):.4f}; floor {floor:.4f}; shares {np.round(shares[:3], 3)}; acf0 {ev[0][1]:.3f}")
    print(f"NUMPY_BENCH mode={'lstsq' if NAIVE else 'bordered'} total_s={total:.4f} diagnose_s={t_diag:.4f} read_s={t_read:.4f}")


if __name__ == "__main__":
    args = sys.argv[1:]
    if args and args[0] == "--lstsq":
        NAIVE = True
        args = args[1:]
    if len(args) != 2:
        sys.exit(__doc__)
    main(args[0], args[1])
