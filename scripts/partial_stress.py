"""Random partial-transport problems on the three geometries (docs/partial.md, "Robustness"):
N from 1 to 399 sites, clustered down to a spread of 1e-4 (plane sites may lie outside the unit
square), masses log-uniform over up to 10³, 2–97 % of the source transported. Prints the count of
each outcome and the first failures. Invalid random inputs (duplicates, points outside the Klein
disk, all sites in a hemisphere) come back as ValueError and are counted as such.

    PYTHONPATH=build/python /usr/bin/python3 scripts/partial_stress.py SEED COUNT
"""
import sys, numpy as np, sdot, collections
rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
stats = collections.Counter(); fails = []
SQ = np.array([[-0.6,-0.6],[0.6,-0.6],[0.6,0.6],[-0.6,0.6]])
for trial in range(int(sys.argv[2]) if len(sys.argv) > 2 else 150):
    geometry = ("plane", "sphere", "hyperbolic")[trial % 3]
    n = int(rng.integers(1, 400))
    spread = 10 ** rng.uniform(-4, 0)
    kw = {}
    if geometry == "plane":
        c = rng.random(2); sites = c + spread * rng.normal(size=(n, 2)); source = 1.0
        if rng.random() < 0.5: sites = np.clip(sites, 0, 1)
    elif geometry == "sphere":
        c = rng.normal(size=3); c /= np.linalg.norm(c)
        s = rng.normal(size=(n, 3)); s /= np.linalg.norm(s, axis=1, keepdims=True)
        k = max(1, n // 2); s[:k] = c + spread * rng.normal(size=(k, 3)); s /= np.linalg.norm(s, axis=1, keepdims=True)
        sites = s; kw = {"geometry": "sphere"}; source = 4 * np.pi
    else:
        sites = np.clip(rng.uniform(-0.5, 0.5, 2) + spread * rng.normal(size=(n, 2)), -0.9, 0.9)
        kw = {"geometry": "hyperbolic", "model": "klein", "domain": SQ}; source = 2.38962566658
    fraction = rng.uniform(0.02, 0.97)
    masses = 10 ** rng.uniform(0, rng.uniform(0, 3), n); masses *= fraction * source / masses.sum()
    try:
        r = sdot.solve(sites, masses, partial=True, tolerance=1e-9, **kw)
        stats[(geometry, r.status)] += 1
        if not r.usable: fails.append((trial, geometry, n, spread, fraction, r.message))
        if not np.all(np.isfinite(r.weights)): fails.append((trial, "NaN"))
    except ValueError as e:
        stats[(geometry, "ValueError")] += 1; fails.append((trial, geometry, n, spread, fraction, str(e)[:150]))
print(sorted(stats.items()))
for f in fails[:12]: print(f)
