"""docs/python.md as one script: train Van der Pol from Python, run every filter on a NumPy record, plot.
Run from the repository root: PYTHONPATH=build/python python3 examples/python/vanderpol.py [OUT_DIR]"""
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import hinf

out = sys.argv[1] if len(sys.argv) > 1 else "runs/out/python-vanderpol"

# 1. the config: f, g, h written as expressions (runs/vanderpol.toml, docs/byos.md)
cfg = hinf.Config("runs/vanderpol.toml")
print(cfg, cfg.state_names, "dt =", cfg.dt, "t_final =", cfg.t_final)

# 2. train, with a progress callback (a print every 500 time steps)
def progress(p):
    if p.step % 500 == 0:
        print(f"  step {p.step}/{p.last_step}  t = {p.t:5.2f} s  loss {p.loss_last:.3g}  HJIE violations {p.violation:.3f}")

report = hinf.train(cfg, out, progress=progress, force=True)
print({k: report[k] for k in ("last_step", "wall_seconds", "fraction_steps_violation_ok", "mean_cosine")})

# 3. a record as NumPy arrays: the config's own system and Euler step, noise as [online] says (0.5, 0.1)
rng = np.random.default_rng(0)
K = 2000
t = np.arange(K) * cfg.dt
x = cfg.initial_state
X = np.empty((K, cfg.states))
Y = np.empty((K, cfg.outputs))
for k in range(K):
    X[k] = x
    Y[k] = cfg.measure(x, t[k]) + 0.1 * rng.standard_normal(cfg.outputs)
    x = cfg.advance(x, 0.5 * rng.standard_normal(cfg.disturbances), t[k])

# 4. every filter on the record: run() returns NumPy arrays (estimates, covariances, innovations)
filters = hinf.filters(cfg, "dnn,ekf,ukf,pf,open_loop", network=out + "/checkpoint.h5")
traces = {f.name: f.run(t, Y) for f in filters}
settled = t >= 5.0
for name, tr in traces.items():
    err = tr.xhat - X
    rmse = np.sqrt(np.mean(err[settled, 0] ** 2))
    print(f"{name:26s} position RMSE after 5 s {rmse:.4f} m   innovation rms {tr.innovation_rms[0]:.4f}"
          f"   covariance {'yes' if tr.covariance is not None else 'no'}")

# 5. plot: truth and estimates of the position, and the EKF's 2-sigma band
fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
ax[0].plot(t, X[:, 0], "k", lw=2, label="truth")
for name, tr in traces.items():
    ax[0].plot(t, tr.xhat[:, 0], lw=1, label=name)
ax[0].set_ylabel("position p [m]")
ax[0].legend(ncol=3, fontsize=8)
for name, tr in traces.items():
    ax[1].semilogy(t, np.abs(tr.xhat[:, 0] - X[:, 0]) + 1e-6, lw=0.8, label=name)
sd = np.sqrt(traces["ekf"].covariance[:, 0, 0])
ax[1].semilogy(t, 2 * sd, "k--", lw=0.8, label="EKF 2σ")
ax[1].set_ylabel("|position error| [m]")
ax[1].set_xlabel("t [s]")
ax[1].legend(ncol=3, fontsize=8)
fig.tight_layout()
fig.savefig(out + "/filters.png", dpi=110)
print("figure:", out + "/filters.png")

# 6. the files hinf writes, back as dicts of NumPy arrays
traj = hinf.read_results(out + "/trajectory.h5")
print("trajectory.h5:", sorted(k for k in traj if k != "attrs")[:6], "...", traj["t"].shape)
