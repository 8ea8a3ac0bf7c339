"""pytest over the Python module: bit for bit against the `hinf` program on the same record, the progress callback,
and bad use raising hinf.Error with hinf's one-line message. Run: PYTHONPATH=build/python HINF_CLI=build/hinf
python3 -m pytest python/tests (ctest runs it as python_pytest; scripts/test also against the installed module)."""
import os
import shutil
import subprocess

import numpy as np
import pytest

import hinf

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
VANDERPOL = os.path.join(ROOT, "runs", "vanderpol.toml")
SMALL = ["training.samples=400", "training.batch=200", "training.adam_steps=5"]


def hinf_cli():
    cli = os.environ.get("HINF_CLI") or shutil.which("hinf")
    assert cli, "set HINF_CLI to the hinf program (build/hinf)"
    return cli


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    d = tmp_path_factory.mktemp("vanderpol")
    cfg = hinf.Config(VANDERPOL, set=SMALL)
    seen = []
    report = hinf.train(cfg, str(d / "run"), until=0.3, progress=seen.append)
    return cfg, str(d / "run" / "checkpoint.h5"), report, seen, d


@pytest.fixture(scope="session")
def record(trained):
    """A noisy Van der Pol record simulated with the config's own Euler step, written as CSV (17 digits)."""
    cfg, _, _, _, d = trained
    rng = np.random.default_rng(5)
    K = 600
    t = np.arange(K) * cfg.dt
    Y = np.empty((K, cfg.outputs))
    x = cfg.initial_state
    for k in range(K):
        Y[k] = cfg.measure(x, t[k]) + 0.1 * rng.standard_normal(cfg.outputs)
        x = cfg.advance(x, 0.5 * rng.standard_normal(cfg.disturbances), t[k])
    path = str(d / "record.csv")
    np.savetxt(path, np.column_stack([t, Y]), delimiter=",", fmt="%.17g", header="t,y", comments="")
    return t, Y, path


def test_train_reports_progress_every_step(trained):
    cfg, ckpt, report, seen, _ = trained
    assert not report["diverged"] and report["last_step"] == 30 and os.path.exists(ckpt)
    assert [p.step for p in seen] == list(range(1, 31))
    assert all(p.last_step == 30 for p in seen) and np.isfinite([p.loss_last for p in seen]).all()
    assert seen[-1].t == pytest.approx(0.3)


def test_filters_match_hinf_filter_bit_for_bit(trained, record, tmp_path):
    cfg, ckpt, _, _, _ = trained
    t, Y, path = record
    names = "dnn,ekf,ukf,pf,open_loop"
    subprocess.run([hinf_cli(), "filter", VANDERPOL, "--network", ckpt, "--measurements", path, "--filters", names,
                    "--particles", "300", "--quiet", "--out", str(tmp_path)], check=True, capture_output=True)
    written = hinf.read_results(str(tmp_path / "estimates.h5"))
    assert written["attrs"]["format"] == "hinf-estimates"
    # the CLI's config has no overrides: the Python side loads the same file
    filters = hinf.filters(hinf.Config(VANDERPOL), names, network=ckpt, particles=300)
    assert [f.name for f in filters] == ["dnn_dissipative_measured", "ekf", "ukf", "pf", "open_loop"]
    for f in filters:
        trace = f.run(t, Y)
        g = written[f.name]
        assert np.array_equal(trace.xhat, g["xhat"]), f.name
        assert np.array_equal(trace.innovation, g["innovation"]), f.name
        assert np.array_equal(trace.xhat_final, g["xhat_final"]), f.name
        if f.has_covariance:
            assert np.array_equal(trace.covariance, g["P"]), f.name
        else:
            assert trace.covariance is None and "P" not in g
        assert trace.diverged_at == g["attrs"]["diverged_at"]


def test_glf_on_the_missile_matches_hinf_filter_bit_for_bit(tmp_path):
    """glf needs an LMI design the Van der Pol system has none for (SDPA: infeasible); the missile has one."""
    config = os.path.join(ROOT, "runs", "missile_hinf.toml")
    cfg = hinf.Config(config)
    rng = np.random.default_rng(2)
    K = 150
    t = np.arange(K) * cfg.dt
    Y = np.empty((K, cfg.outputs))
    x = cfg.initial_state
    for k in range(K):
        Y[k] = cfg.measure(x, t[k]) + 20 * rng.standard_normal(cfg.outputs)
        x = cfg.advance(x, 20 * rng.standard_normal(cfg.disturbances), t[k])
    path = str(tmp_path / "record.csv")
    np.savetxt(path, np.column_stack([t, Y]), delimiter=",", fmt="%.17g")
    subprocess.run([hinf_cli(), "filter", config, "--measurements", path, "--filters", "glf,ekf", "--quiet", "--out",
                    str(tmp_path)], check=True, capture_output=True)
    written = hinf.read_results(str(tmp_path / "estimates.h5"))
    for f in hinf.filters(cfg, "glf,ekf"):
        trace = f.run(t, Y)
        assert np.array_equal(trace.xhat, written[f.name]["xhat"]), f.name
        assert np.array_equal(trace.innovation, written[f.name]["innovation"]), f.name


def test_step_by_step_equals_run(trained, record):
    cfg, ckpt, _, _, _ = trained
    t, Y, _ = record
    for name in ("dnn", "ekf"):
        f = hinf.Filter(cfg, name, network=hinf.Network(ckpt) if name == "dnn" else None)
        trace = f.run(t, Y)
        xs, Ps = [], []
        for k in range(len(t)):
            xs.append(f.estimate)
            if f.has_covariance:
                Ps.append(f.covariance)
            assert f.step(Y[k], t[k])
        # the record's interval (t[-1] - t[0]) / (K - 1) may differ from dt in the last bit: compare to round-off
        np.testing.assert_allclose(np.array(xs), trace.xhat, rtol=1e-9, atol=1e-12)
        if Ps:
            np.testing.assert_allclose(np.array(Ps), trace.covariance, rtol=1e-9, atol=1e-12)
        f.reset()
        assert np.array_equal(f.estimate, cfg.initial_estimate)


def test_network_gradient_shapes(trained):
    _, ckpt, _, _, _ = trained
    net = hinf.Network(ckpt)
    assert net.variant == "dissipative" and net.config.states == 2
    one = net.gradient(np.array([0.1, -0.2]))
    many = net.gradient(np.array([[0.1, -0.2], [0.3, 0.4]]))
    assert one.shape == (2,) and many.shape == (2, 2) and np.array_equal(many[0], one)
    assert net.value(np.array([0.1, -0.2])) > 0  # the quadratic head's V is positive away from 0


def one_line_error(call, fragment):
    with pytest.raises(hinf.Error) as err:
        call()
    text = str(err.value)
    assert fragment in text, text
    assert "\n" not in text
    return text


def test_bad_use_raises_hinf_error(trained, record, tmp_path):
    cfg, ckpt, _, _, _ = trained
    t, Y, _ = record
    f = hinf.Filter(cfg, "ekf")
    one_line_error(lambda: f.run(t, np.column_stack([Y, Y])), "expected (600, 1)")
    one_line_error(lambda: f.run(t[:, None], Y), "t has shape (600, 1)")
    one_line_error(lambda: f.run(t[:10], Y), "y has shape (600, 1); expected (10, 1)")
    one_line_error(lambda: f.run(t[::-1].copy(), Y), "time must increase strictly")
    one_line_error(lambda: f.step(np.zeros(3), 0.0), "Filter.step: y has shape (3,)")
    one_line_error(lambda: hinf.Filter(cfg, "kalman"), "unknown filter 'kalman'")
    one_line_error(lambda: hinf.Filter(cfg, "dnn"), "needs a trained network")
    one_line_error(lambda: hinf.Config(str(tmp_path / "none.toml")), "none.toml")
    one_line_error(lambda: hinf.Network(str(tmp_path / "none.h5")), "none.h5")
    # a network trained for another system: a 2-state expression system with other names
    other = hinf.Config.from_text(
        open(VANDERPOL).read().replace('states = ["p", "w"]', 'states = ["q", "v"]')
        .replace('"w"', '"v"').replace("mu*(1 - p^2)*w - p", "-q - v").replace('"p + c*p^3"', '"q"'), "other.toml")
    one_line_error(lambda: hinf.Filter(other, "dnn", network=ckpt), "was trained for the system")
    # a missile checkpoint against the Van der Pol config
    missile = hinf.Config.from_text('[system]\nkind = "missile"\n[filter]\nt_final = 0.02\n[network]\nhidden = [4]\n'
                                    '[training]\nsamples = 20\nbatch = 10\nadam_steps = 1\ncheckpoint_every = 1\n')
    hinf.train(missile, str(tmp_path / "missile"))
    one_line_error(lambda: hinf.Filter(cfg, "dnn", network=str(tmp_path / "missile" / "checkpoint.h5")),
                   "trained for 6 states")
    one_line_error(lambda: hinf.train(missile, str(tmp_path / "missile")), "already holds a run")


def test_callback_exception_stops_training_and_keeps_checkpoint(tmp_path):
    cfg = hinf.Config(VANDERPOL, set=SMALL + ["training.checkpoint_every=2"])

    def stop(p):
        if p.step == 5:
            raise KeyError("stop here")

    with pytest.raises(KeyError):
        hinf.train(cfg, str(tmp_path / "run"), until=0.1, progress=stop)
    ckpt = str(tmp_path / "run" / "checkpoint.h5")
    assert os.path.exists(ckpt)
    report = hinf.resume(ckpt, until=0.1)
    assert report["first_step"] == 4 and report["last_step"] == 10
