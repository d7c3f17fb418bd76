"""The largest velocity error of each vortex solver against the exact velocity of
the blob-regularised Lamb-Oseen vortex (docs/models.md, vortex studies).

Run from the project folder after `cargo build --release`:
    python3 scripts/vortex-velocity-error.py
"""
import csv, math, os, subprocess, tempfile
B = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "target", "release", "cellist")
def scen(h, vel, steps=0, remesh=0):
    return f'''model = "vortex"
[system]
initial = {{ kind = "lamb-oseen", circulation = 1.0, t0 = 1.0, spacing = {h}, extent = 0.9 }}
nu = 0.01
sigma_over_h = 1.5
velocity = {vel}
remesh_every = {remesh}
[run]
steps = {steps}
dt = 0.02
[output]
thermo_every = 5
field = {{ every = 5, file = "w.csv" }}
png = {{ every = 0 }}
gif = {{ every = 0 }}
'''
work = tempfile.mkdtemp()
os.chdir(work)
for h in [0.05, 0.025]:
  for name, vel in [("direct",'{ kind = "direct" }'),("tree 0.3",'{ kind = "barnes-hut", theta = 0.3 }'),("tree 0.6",'{ kind = "barnes-hut", theta = 0.6 }'),("mesh 64",'{ kind = "mesh", grid = 64 }'),("mesh 128",'{ kind = "mesh", grid = 128 }'),("mesh 256",'{ kind = "mesh", grid = 256 }')]:
    open("v.toml","w").write(scen(h, vel))
    subprocess.run([B,"run","v.toml","--out","vout"],capture_output=True,check=True)
    rows=list(csv.DictReader(open("vout/w_0.csv")))
    nu,sig=0.01,1.5*h; age=1+sig*sig/(2*nu)
    worst=peak=0
    for r in rows:
        x,y=float(r['x']),float(r['y']); rr=math.hypot(x,y)
        s=0 if rr==0 else -math.expm1(-rr*rr/(4*nu*age))/(2*math.pi*rr)
        ex=(0,0) if rr==0 else (-s*y/rr, s*x/rr)
        worst=max(worst, math.hypot(float(r['u'])-ex[0], float(r['v'])-ex[1])); peak=max(peak,s)
    print(h, name, len(rows), "%.2e"%(worst/peak))
