"""hinf from Python: H-infinity filters designed by training a network on the HJI equation, and their baselines.

    import hinf
    cfg = hinf.Config("runs/vanderpol.toml")
    hinf.train(cfg, "runs/out/vanderpol", progress=lambda p: print(p.step, p.loss_last))
    dnn = hinf.Filter(cfg, "dnn", network="runs/out/vanderpol/checkpoint.h5")
    trace = dnn.run(t, Y)          # NumPy in, NumPy out: trace.xhat [K x n], trace.innovation [K x m]
    table = hinf.compare(cfg, "runs/out/vanderpol/compare", network="runs/out/vanderpol/checkpoint.h5")

Errors in the caller's terms raise hinf.Error (a RuntimeError) with hinf's one-line message. docs/python.md.
"""
from ._hinf import (Config, Error, Filter, FilterTrace, Network, TrainProgress, compare, export_c, filter_names,
                    filters, replay_worst, resume, train, version, worst)

__all__ = ["Config", "Error", "Filter", "FilterTrace", "Network", "TrainProgress", "compare", "export_c",
           "filter_names", "filters", "read_results", "replay_worst", "resume", "train", "version", "worst"]


def read_results(path):
    """Reads a result file hinf writes (estimates.h5, operate.h5, compare.h5, trajectory.h5, checkpoint.h5, ...)
    into nested dicts: datasets as NumPy arrays, groups as dicts, attributes under the key "attrs".
    Needs h5py (Debian python3-h5py). Layouts: docs/formats.md."""
    try:
        import h5py
    except ImportError as err:  # one line in the caller's terms
        raise Error(f"read_results: reading {path} needs h5py (apt-get install python3-h5py)") from err
    import os

    if not os.path.exists(path):
        raise Error(f"read_results: {path} does not exist (check the path)")

    def attrs(obj):
        out = {}
        for k, v in obj.attrs.items():
            out[k] = v.decode() if isinstance(v, bytes) else v
        return out

    def group(g):
        out = {"attrs": attrs(g)}
        for k, v in g.items():
            if isinstance(v, h5py.Group):
                out[k] = group(v)
            else:
                data = v[()]
                out[k] = data.decode() if isinstance(data, bytes) else data
        return out

    try:
        with h5py.File(path, "r") as f:
            return group(f)
    except OSError as err:
        raise Error(f"read_results: {path} is not a readable HDF5 file ({err})") from err
