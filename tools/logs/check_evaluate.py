"""An independent recomputation of `constraint_dynamics evaluate`'s figures.

    .venv-logs/bin/python tools/logs/check_evaluate.py EVALUATE_JSON BAG [REFERENCE_TOPIC]

EVALUATE_JSON is the output of `evaluate --records`. The bag is read again here by another
reader (mcap-ros2-support's, with its own CDR decoder); for every prediction the reference pose
at or before t0 + h is looked up in it, the errors and NEES are recomputed from the predicted
pose and covariance the tool printed, and the summary (median, p95, max, coverage, mean NEES)
from those with NumPy, and the χ²(3) bounds from the closed-form CDF. The coverages' 95 %
intervals are recomputed as the roots of the score test's quadratic, (p̂ − π)² = z² π (1 − π)/m,
on the effective count m that docs/logs.md states, the start period read from the records'
start times. Exits 1 naming the first figure that disagrees.
"""

import json
import math
import sys

import numpy as np
from mcap_ros2.reader import read_ros2_messages


def chi2_3_cdf(x):
    """P(χ²(3) ≤ x) = erf(√(x/2)) − √(2x/π) e^(−x/2)."""
    return math.erf(math.sqrt(x / 2)) - math.sqrt(2 * x / math.pi) * math.exp(-x / 2)


def chi2_3_quantile(p):
    lo, hi = 0.0, 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chi2_3_cdf(mid) < p else (lo, mid)
    return 0.5 * (lo + hi)


def normal_quantile(p):
    lo, hi = 0.0, 10.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if 0.5 * (1 + math.erf(mid / math.sqrt(2))) < p else (lo, mid)
    return 0.5 * (lo + hi)


def score_interval(p, m):
    """The π where the score test of a fraction p among m trials sits at its two-sided 5 %
    bound: the roots of (1 + z²/m) π² − (2p + z²/m) π + p² = 0."""
    z2 = normal_quantile(0.975) ** 2
    roots = np.sort(np.roots([1 + z2 / m, -(2 * p + z2 / m), p * p]).real)
    return max(0.0, roots[0]), min(1.0, roots[1])


def independent_count(n, every, h):
    """n / (1 + 2 Σ ρ²) over the lags at which two predictions overlap, ρ = 1 − lag every/h."""
    lags = np.arange(1, int(np.ceil(h / every - 1e-9)))
    return n / (1 + 2 * np.sum((1 - lags * every / h) ** 2))


def read_reference(bag, topic):
    """(stamps [ns], poses (x, y, yaw), covariances 3×3) of `topic`, in file order."""
    import glob
    import os
    files = sorted(glob.glob(os.path.join(bag, "*.mcap"))) if os.path.isdir(bag) else [bag]
    t, poses, covs = [], [], []
    for f in files:
        for m in read_ros2_messages(f, topics=[topic]):
            o = m.ros_msg
            s = o.header.stamp
            q = o.pose.pose.orientation
            yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
            c = np.array(o.pose.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
            t.append(s.sec * 10**9 + s.nanosec)
            poses.append((o.pose.pose.position.x, o.pose.pose.position.y, yaw))
            covs.append(c)
    return np.array(t, dtype=np.int64), np.array(poses), np.array(covs)


def close(name, got, want, tol):
    if not abs(got - want) <= tol * max(1.0, abs(want)):
        sys.exit(f"check_evaluate: {name}: evaluate printed {got}, recomputed {want}")


def main():
    out = json.load(open(sys.argv[1]))
    bag = sys.argv[2]
    topic = sys.argv[3] if len(sys.argv) > 3 else "/odom"
    stamps, poses, covs = read_reference(bag, topic)
    origin = None
    records = out["records"]
    by_h = {}
    b50, b95 = chi2_3_quantile(0.5), chi2_3_quantile(0.95)
    for r in records:
        # The origin is the bag's earliest stamp; recover it from the first record's reference
        # time and check every other record against it.
        t_end_ns = None
        if origin is None:
            k = int(np.argmin(np.abs(stamps - (stamps[0] + round(r["reference_t_s"] * 1e9)))))
            origin = stamps[k] - round(r["reference_t_s"] * 1e9)
        t_end_ns = origin + round((r["t0_s"] + r["horizon_s"]) * 1e9)
        k = int(np.searchsorted(stamps, t_end_ns, side="right")) - 1
        close("reference time", r["reference_t_s"], (stamps[k] - origin) * 1e-9, 1e-9)
        for i in range(3):
            close(f"reference pose[{i}]", r["reference"][i], poses[k][i], 1e-12)
        e = np.array(poses[k]) - np.array(r["predicted"])
        e[2] = (e[2] + math.pi) % (2 * math.pi) - math.pi
        s = np.array(r["predicted_covariance"]) + covs[k]
        nees = float(e @ np.linalg.solve(s, e))
        close("position error", r["position_error_m"], math.hypot(e[0], e[1]), 1e-9)
        close("yaw error", r["yaw_error_rad"], e[2], 1e-9)
        close("nees", r["nees"], nees, 1e-6)
        by_h.setdefault(r["horizon_s"], []).append((math.hypot(e[0], e[1]), abs(e[2]), nees))
    t0s = np.unique([r["t0_s"] for r in records])
    every = float(np.median(np.diff(t0s))) if len(t0s) > 1 else 1.0
    for h in out["horizons"]:
        rows = np.array(by_h[h["horizon_s"]])
        close(f"{h['horizon_s']} s predictions", h["predictions"], len(rows), 0)
        for col, key in [(0, "position_error_m"), (1, "yaw_error_rad")]:
            close(f"{h['horizon_s']} s {key} median", h[key]["median"], np.median(rows[:, col]), 1e-9)
            close(f"{h['horizon_s']} s {key} p95", h[key]["p95"], np.percentile(rows[:, col], 95), 1e-9)
            close(f"{h['horizon_s']} s {key} max", h[key]["max"], rows[:, col].max(), 1e-12)
        close(f"{h['horizon_s']} s coverage p50", h["coverage"]["p50"], np.mean(rows[:, 2] <= b50), 1e-12)
        close(f"{h['horizon_s']} s coverage p95", h["coverage"]["p95"], np.mean(rows[:, 2] <= b95), 1e-12)
        m = independent_count(len(rows), every, h["horizon_s"])
        close(f"{h['horizon_s']} s independent predictions", h["coverage"]["independent_predictions"], m, 1e-6)
        for b, key in [(b50, "p50"), (b95, "p95")]:
            lo, hi = score_interval(np.mean(rows[:, 2] <= b), m)
            close(f"{h['horizon_s']} s coverage {key} interval low", h["coverage"][f"{key}_interval"][0], lo, 1e-6)
            close(f"{h['horizon_s']} s coverage {key} interval high", h["coverage"][f"{key}_interval"][1], hi, 1e-6)
        close(f"{h['horizon_s']} s nees_mean", h["nees_mean"], rows[:, 2].mean(), 1e-6)
    print(f"check_evaluate: {len(records)} predictions and {len(out['horizons'])} horizons agree")


if __name__ == "__main__":
    main()
