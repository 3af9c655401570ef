#!/usr/bin/env python3
# Round trips at parameter sets drawn at random (README, "Round trips at random"): each case is
# rendered by `phongfit render`, fitted back by `phongfit fit` from kd, ks 0.3 and n 100 times
# broader, and printed with its largest deviation in standard errors; rows.json keeps them all.
# Usage: scripts/random_round_trips.py PHONGFIT OUT_DIR [CASES [SEED [SCENES]]]
# SCENES (comma-separated, of the eight below) draws those alone, the other draws as with all, e.g.
#   scripts/random_round_trips.py build/phongfit ra87 40 87 cornell_area
import json, math, os, random, subprocess, sys
B = sys.argv[1]
OUT = sys.argv[2]
N = int(sys.argv[3]) if len(sys.argv) > 3 else 60
SC = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'datasets_synth', 'scenes')
SHARED = os.path.abspath(os.path.join(SC, '../../../shared'))
rng = random.Random(int(sys.argv[4]) if len(sys.argv) > 4 else 79)
scenes = ['sphere_point', 'sphere_directional', 'sphere_quad', 'sphere_sharp_area', 'sphere_envmap',
          'sphere_orbit', 'cornell_point', 'cornell_area']
only = sys.argv[5].split(',') if len(sys.argv) > 5 else []
for s in only:
    if s not in scenes: sys.exit(f'unknown scene {s} (allowed: {", ".join(scenes)})')
filters = {'box': None, 'gaussian': '<rfilter type="gaussian"/>', 'tent': '<rfilter type="tent"/>'}
os.makedirs(OUT, exist_ok=True)
for f, rf in filters.items():
    if rf is None: continue
    for s in scenes:
        t = open(f'{SC}/{s}.xml').read().replace('<rfilter type="box"/>', rf)
        t = t.replace('../../../shared', SHARED)
        open(f'{OUT}/{s}_{f}.xml', 'w').write(t)
rows = []
for i in range(N):
    s = rng.choice(scenes)
    if only: s = only[scenes.index(s) % len(only)]
    f = rng.choice(list(filters))
    cornell = s.startswith('cornell')
    size = rng.choice([64, 96, 128] if cornell else [64, 96, 128, 192, 256])
    n = math.exp(rng.uniform(math.log(1), math.log(30000)))
    r = rng.random()
    ks = 0.0 if r < 0.15 else (0.02 if r < 0.25 else rng.uniform(0.05, 0.7))
    if rng.random() < 0.3:
        kd = [rng.uniform(0.02, 1 - ks) for _ in range(3)]
    else:
        kd = [rng.uniform(0.05, 1 - ks)] * 3
    if rng.random() < 0.1: kd = [1 - ks] * 3  # kd + ks = 1
    spp = rng.choice([256, 1024]) if not cornell else 256
    scene = f'{SC}/{s}.xml' if f == 'box' else f'{OUT}/{s}_{f}.xml'
    name = f'c{i:03d}'
    kds = ','.join('%.6g' % x for x in kd)
    defs = ['-D', f'width={size}', '-D', f'height={size}', '-D', f'n={n:.6g}', '-D', f'ks={ks:.6g}',
            '-D', f'kd={kds}', '-D', f'spp={spp}']
    if cornell: defs += ['-D', 'maxDepth=5']
    img = f'{OUT}/{name}.exr'
    if not os.path.exists(img):
        subprocess.run([B, 'render', scene, '-o', img, '--quiet'] + defs, capture_output=True)
    fo = f'{OUT}/{name}_fit'
    p = subprocess.run([B, 'fit', '--view', f'{scene}:{img}', '--material', 'sphere', '-o', fo, '--quiet',
                        '--kd', '0.3', '--ks', '0.3', '--n', '%.6g' % max(n / 100, 0.01)] + defs,
                       capture_output=True, text=True)
    try:
        j = json.load(open(f'{fo}/fit.json'))
    except Exception:
        print(name, 'FAILED', p.stderr[-300:]); continue
    m = j['materials']['sphere']
    row = dict(name=name, scene=s, filter=f, size=size, n=n, ks=ks, kd=kd, spp=spp,
               fn=m['n'], fn_std=m['n_std'], fkd=m['kd'], fkd_std=m['kd_std'], fks=m['ks'], fks_std=m['ks_std'],
               unc=m['unconstrained'], conv=j['converged'], stop=j['stop_reason'], time=j['time_s'],
               edges=[v['edges']['agree'] for v in j['views']], misfit=[v['edges']['misfit'] for v in j['views']])
    rows.append(row)
    def z(t, e, sd):
        return abs(e - t) / sd if sd > 0 else (0 if e == t else float('inf'))
    zs = [z(n, m['n'], m['n_std']) if 'n' not in m['unconstrained'] else 0]
    zs += [z(kd[c], m['kd'][c], m['kd_std'][c]) for c in range(3)]
    zs += [z(ks, m['ks'][c], m['ks_std'][c]) if 'ks' not in m['unconstrained'] else 0 for c in range(3)]
    print(f"{name} {s} {f} {size} spp{spp} n {n:.4g}->{m['n']:.4g}±{m['n_std']:.2g} ks {ks:.3g}->{m['ks'][0]:.3g}±{m['ks_std'][0]:.2g} "
          f"kd {kd[0]:.3g}->{m['kd'][0]:.3g}±{m['kd_std'][0]:.2g} unc {m['unconstrained']} {j['stop_reason']} "
          f"edges {row['edges']} maxz {max(zs):.2f} t {j['time_s']:.2f}", flush=True)
json.dump(rows, open(f'{OUT}/rows.json', 'w'), indent=1)
