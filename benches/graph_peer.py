"""GTSAM's Levenberg-Marquardt beside `pirouette graph optimise` on the same
g2o files, from the same starting poses, in one run.

Both final poses are scored with the same g2o-style chi² (the sum over
edges of eᵀΩe, e the (x, y, θ) of z⁻¹·(xi⁻¹·xj)). Times are medians over
repeated runs: GTSAM's optimize() call; pirouette's own `time_s`
(initialisation and optimisation, without reading the file). Run by
graph_peer.sh, which installs GTSAM into a local virtual environment.
"""

import json
import math
import statistics
import subprocess
import sys
import tempfile
import time

import gtsam
import numpy as np


def read_g2o(path):
    vertices, edges = {}, []
    with open(path) as f:
        for line in f:
            t = line.split('#')[0].split()
            if not t:
                continue
            if t[0] == 'VERTEX_SE2':
                vertices[int(t[1])] = (float(t[2]), float(t[3]), float(t[4]))
            elif t[0] == 'EDGE_SE2':
                i, j = int(t[1]), int(t[2])
                z = tuple(float(v) for v in t[3:6])
                a = [float(v) for v in t[6:12]]
                info = np.array([[a[0], a[1], a[2]], [a[1], a[3], a[4]], [a[2], a[4], a[5]]])
                edges.append((i, j, z, info))
    return vertices, edges


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), s * a[0] - c * a[1], -a[2])


def chain(edges):
    """Odometry chaining from pose 0, as pirouette's init::chain does."""
    ids = sorted({i for e in edges for i in e[:2]})
    poses = {ids[0]: (0.0, 0.0, 0.0)}
    for i, j, z, _ in edges:
        if j == i + 1 and i in poses and j not in poses:
            poses[j] = compose(poses[i], z)
    changed = True
    while changed:
        changed = False
        for i, j, z, _ in edges:
            if i in poses and j not in poses:
                poses[j] = compose(poses[i], z)
                changed = True
            elif j in poses and i not in poses:
                poses[i] = compose(poses[j], inverse(z))
                changed = True
    return poses


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def g2o_chi2(poses, edges):
    total = 0.0
    for i, j, z, info in edges:
        r = compose(inverse(z), compose(inverse(poses[i]), poses[j]))
        e = np.array([r[0], r[1], wrap(r[2])])
        total += float(e @ info @ e)
    return total


def gtsam_run(initial_poses, edges):
    graph = gtsam.NonlinearFactorGraph()
    first = min(initial_poses)
    graph.add(gtsam.PriorFactorPose2(first, gtsam.Pose2(*initial_poses[first]),
                                     gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-8]))))
    for i, j, z, info in edges:
        graph.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*z), gtsam.noiseModel.Gaussian.Information(info)))
    values = gtsam.Values()
    for k, p in initial_poses.items():
        values.insert(k, gtsam.Pose2(*p))
    params = gtsam.LevenbergMarquardtParams()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    t0 = time.perf_counter()
    result = optimizer.optimize()
    elapsed = time.perf_counter() - t0
    poses = {k: (result.atPose2(k).x(), result.atPose2(k).y(), result.atPose2(k).theta()) for k in initial_poses}
    # GTSAM's own figure: twice its error, the sum of its residuals' eᵀΩe
    # (the prior's share is negligible at the held pose).
    return poses, elapsed, optimizer.iterations(), 2.0 * graph.error(result)


def main():
    binary, runs, files = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    print(f"{'graph':<16} {'poses':>6} {'edges':>6} | {'GTSAM LM chi²':>14} {'iter':>4} {'time s':>8} | "
          f"{'pirouette chi²':>14} {'iter':>4} {'time s':>8} | {'chi² diff':>9} {'time ratio':>10}")
    log_rows = []
    for path in files:
        vertices, edges = read_g2o(path)
        initial = vertices if vertices else chain(edges)
        g_times, p_times = [], []
        for _ in range(runs):
            g_poses, g_time, g_iter, g_own = gtsam_run(initial, edges)
            g_times.append(g_time)
            with tempfile.TemporaryDirectory() as d:
                out = subprocess.run([binary, 'graph', 'optimise', path, '--out', f'{d}/out.g2o', '--json'],
                                     check=True, capture_output=True, text=True).stdout
            p = json.loads(out)
            p_times.append(p['time_s'])
        g_chi2 = g2o_chi2(g_poses, edges)
        name = path.rsplit('/', 1)[-1]
        diff = (p['chi2_final'] - g_chi2) / g_chi2
        g_t, p_t = statistics.median(g_times), statistics.median(p_times)
        print(f"{name:<16} {len(initial):>6} {len(edges):>6} | {g_chi2:>14.6f} {g_iter:>4} {g_t:>8.4f} | "
              f"{p['chi2_final']:>14.6f} {p['iterations']:>4} {p_t:>8.4f} | {diff:>+9.2e} {p_t / g_t:>10.3f}")
        # The same, both minimising (and scored in) GTSAM's log residual.
        with tempfile.TemporaryDirectory() as d:
            out = subprocess.run([binary, 'graph', 'optimise', path, '--out', f'{d}/out.g2o', '--json',
                                  '--residual', 'log'], check=True, capture_output=True, text=True).stdout
        q = json.loads(out)
        log_rows.append((name, g_own, q['cost_final'], (q['cost_final'] - g_own) / g_own))
    print("\nIn GTSAM's own residual (SE(2) log), pirouette run with --residual log:")
    print(f"{'graph':<16} | {'GTSAM cost':>14} | {'pirouette cost':>14} | {'diff':>9}")
    for name, g_own, p_own, diff in log_rows:
        print(f"{name:<16} | {g_own:>14.6f} | {p_own:>14.6f} | {diff:>+9.2e}")


if __name__ == '__main__':
    main()
