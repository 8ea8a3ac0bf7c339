"""pytest over the Python module: bit for bit against the `hinf` program on the same record (built-in system), the progress callback,
and bad use raising hinf.Error with hinf's one-line message. Run: PYTHONPATH=build/python HINF_CLI=build/hinf
python3 -m pytest python/tests (ctest runs it as python_pytest; scripts/test also against the installed module)."""
import math
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


def run_cli_filter(config, record_path, names, out, network=None):
    args = [hinf_cli(), "filter", config, "--measurements", record_path, "--filters", names, "--particles", "300",
            "--quiet", "--out", str(out)]
    if network:
        args += ["--network", network]
    subprocess.run(args, check=True, capture_output=True)
    written = hinf.read_results(str(out / "estimates.h5"))
    assert written["attrs"]["format"] == "hinf-estimates"
    return written


MISSILE = """[system]
kind = "missile"
[filter]
t_final = 2.0
[network]
hidden = [16, 8]
[training]
samples = 100
batch = 50
adam_steps = 3
checkpoint_every = 5
"""


def test_missile_filters_match_hinf_filter_bit_for_bit(tmp_path):
    """Every filter, built-in system: Filter.run gives the bits of `hinf filter`'s estimates.h5."""
    config = tmp_path / "missile.toml"
    config.write_text(MISSILE)
    cfg = hinf.Config(str(config))
    hinf.train(cfg, str(tmp_path / "run"), until=0.1)
    ckpt = str(tmp_path / "run" / "checkpoint.h5")
    rng = np.random.default_rng(2)
    K = 150
    t = 3.0 + np.arange(K) * cfg.dt  # a record need not start at 0
    Y = np.empty((K, cfg.outputs))
    x = cfg.initial_state
    for k in range(K):
        Y[k] = cfg.measure(x, t[k]) + 20 * rng.standard_normal(cfg.outputs)
        x = cfg.advance(x, 20 * rng.standard_normal(cfg.disturbances), t[k])
    path = str(tmp_path / "record.csv")
    np.savetxt(path, np.column_stack([t, Y]), delimiter=",", fmt="%.17g")
    names = "dnn,ekf,ukf,pf,open_loop,glf"
    written = run_cli_filter(str(config), path, names, tmp_path / "flt", network=ckpt)
    filters = hinf.filters(cfg, names, network=hinf.Network(ckpt), particles=300)
    assert [f.name for f in filters] == ["dnn_gain_measured", "ekf", "ukf", "pf", "open_loop", "glf"]
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
        assert np.array_equal(trace.innovation_rms, g["attrs"]["innovation_rms"]), f.name
        # the innovations' consistency: the Bayesian filters state it, the others do not
        assert ("nis" in g) == (f.name in ("ekf", "ukf", "pf")), f.name
        if "nis" in g:
            assert np.array_equal(trace.nis, g["nis"], equal_nan=True), f.name
            assert trace.nis_per_output == g["attrs"]["nis_per_output"], f.name
        else:
            assert trace.nis is None and np.isnan(trace.nis_per_output), f.name


def test_expression_system_filters_match_hinf_filter(trained, record, tmp_path):
    """Van der Pol as expressions: the same filters, to round-off. GiNaC orders the terms of a sum or product by
    hashes that depend on where its library is loaded, so the printed expressions, and with them the last bits,
    differ from process to process (the `hinf` program's own runs differ alike: docs/python.md)."""
    cfg, ckpt, _, _, _ = trained
    t, Y, path = record
    names = "dnn,ekf,ukf,pf,open_loop"
    written = run_cli_filter(VANDERPOL, path, names, tmp_path, network=ckpt)
    filters = hinf.filters(hinf.Config(VANDERPOL), names, network=ckpt, particles=300)
    assert [f.name for f in filters] == ["dnn_gain_measured", "ekf", "ukf", "pf", "open_loop"]
    for f in filters:
        trace = f.run(t, Y)
        g = written[f.name]
        scale = np.abs(g["xhat"]).max()
        # the float network rounds its input: a last-bit change of x~ can move p by float round-off (1e-7)
        np.testing.assert_allclose(trace.xhat, g["xhat"], rtol=0, atol=1e-5 * scale, err_msg=f.name)
        np.testing.assert_allclose(trace.innovation, g["innovation"], rtol=0, atol=1e-5 * scale, err_msg=f.name)
        assert (trace.covariance is None) == ("P" not in g)


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


def test_gain_trace_notes_an_estimate_far_beyond_training(trained, record):
    """FilterTrace.note: empty on a run inside the box of training's estimates, the state and the span named on a run
    started far beyond it (docs/method.md 16.10), as hinf filter prints it; a filter without a network says nothing."""
    cfg, ckpt, _, _, _ = trained
    t, Y, _ = record
    assert hinf.Filter(cfg, "dnn", network=ckpt).run(t, Y).note == ""
    far = hinf.Filter(cfg, "dnn", network=ckpt, initial_estimate=np.array([400.0, -400.0])).run(t, Y)
    assert " reached " in far.note and "where training's estimates spanned [" in far.note
    assert hinf.Filter(cfg, "ekf", initial_estimate=np.array([400.0, -400.0])).run(t, Y).note == ""


def test_network_gain_shapes(trained):
    """The default variant, gain: K(x^, t) [n x m] from the estimate alone; the error's gradient is refused."""
    _, ckpt, _, _, _ = trained
    net = hinf.Network(ckpt)
    assert net.variant == "gain" and net.config.states == 2
    one = net.gain(np.array([0.5, 1.0]), 0.1)
    many = net.gain(np.array([[0.5, 1.0], [0.3, 0.4]]), 0.1)
    assert one.shape == (2, 1) and many.shape == (2, 2, 1) and np.array_equal(many[0], one)
    assert np.isfinite(many).all() and one[0, 0] > 0  # the position innovation corrects the position upwards
    one_line_error(lambda: net.gradient(np.array([0.1, -0.2])), "use gain(x^, t)")


def test_network_gradient_shapes(tmp_path):
    cfg = hinf.Config(VANDERPOL, set=SMALL + ['filter.variant="dissipative"'])
    hinf.train(cfg, str(tmp_path / "run"), until=0.1)
    net = hinf.Network(str(tmp_path / "run" / "checkpoint.h5"))
    assert net.variant == "dissipative" and net.config.states == 2
    one_line_error(lambda: net.gain(np.array([0.5, 1.0])), "use gradient(x~)")
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


def same_results(a, b, path=""):
    """Two result dicts alike entry by entry (NaN equal), timings and the output directory aside."""
    assert set(a) == set(b), path
    for key in a:
        if key in ("wall_seconds", "us_per_step", "seconds", "rank_seconds", "out_dir", "created"):
            continue
        x, y = a[key], b[key]
        if isinstance(x, dict):
            same_results(x, y, path + "/" + key)
        elif isinstance(x, np.ndarray) and x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), path + "/" + key
        elif isinstance(x, float):
            assert x == y or (math.isnan(x) and math.isnan(y)), path + "/" + key
        else:
            assert np.array_equal(x, y), path + "/" + key


def test_compare_is_hinf_compare(trained, tmp_path):
    """hinf.compare runs `hinf compare`: the same compare.h5, and its table as dicts."""
    cfg, ckpt, _, _, _ = trained
    report = hinf.compare(cfg, str(tmp_path / "lib"), filters="dnn,ekf,ukf,open_loop", network=ckpt, modes="measured",
                          runs=3, scenario="cov_large")
    args = [hinf_cli(), "compare", VANDERPOL, "--filters", "dnn,ekf,ukf,open_loop", "--network", ckpt, "--mode",
            "measured", "--runs", "3", "--scenario", "cov_large", "--quiet", "--out", str(tmp_path / "cli")]
    for s in SMALL:
        args += ["--set", s]
    subprocess.run(args, check=True, capture_output=True)
    assert report["file"] == str(tmp_path / "lib" / "compare.h5") and report["streams_identical"]
    assert report["scenario"] == "cov_large" and report["runs"] == 3 and report["steps"] == 2000
    assert [f["name"] for f in report["filters"]] == ["dnn_gain_measured", "ekf", "ukf", "open_loop"]
    lib, cli = hinf.read_results(report["file"]), hinf.read_results(str(tmp_path / "cli" / "compare.h5"))
    same_results(lib, cli)
    for f in report["filters"]:
        assert f["rmse_position"] == lib[f["name"]]["attrs"]["rmse_position"], f["name"]
    assert report["filters"][1]["nees_per_state"] > 0 and math.isnan(report["filters"][3]["nees_per_state"])
    with pytest.raises(hinf.Error, match="runs must be >= 1"):
        hinf.compare(cfg, str(tmp_path / "bad"), filters="ekf", runs=0)
    with pytest.raises(hinf.Error, match="kalman"):
        hinf.compare(cfg, str(tmp_path / "bad"), filters="kalman", runs=1)


def test_worst_is_hinf_worst(trained, tmp_path):
    """hinf.worst runs `hinf worst`'s search: the same worst.h5, and each filter's worst as dicts."""
    cfg, ckpt, _, _, _ = trained
    report = hinf.worst(cfg, str(tmp_path / "lib"), filters="dnn,ekf", network=ckpt, modes="measured", until=3.0,
                        evals=12, random_starts=1, linear_pieces=4)
    args = [hinf_cli(), "worst", VANDERPOL, "--filters", "dnn,ekf", "--network", ckpt, "--mode", "measured",
            "--until", "3", "--evals", "12", "--random-starts", "1", "--linear-pieces", "4", "--quiet",
            "--out", str(tmp_path / "cli")]
    for s in SMALL:
        args += ["--set", s]
    subprocess.run(args, check=True, capture_output=True)
    assert report["file"] == str(tmp_path / "lib" / "worst.h5") and report["steps"] == 300
    assert [f["name"] for f in report["filters"]] == ["dnn_gain_measured", "ekf"]
    lib, cli = hinf.read_results(report["file"]), hinf.read_results(str(tmp_path / "cli" / "worst.h5"))
    same_results(lib, cli)
    for f in report["filters"]:
        g = lib["filters"][f["name"]]["attrs"]
        assert f["ratio"] == g["ratio"] and f["small_signal"] == g["linear_gain"], f["name"]
        assert f["ratio"] > 0 and not f["diverged"] and f["found_from"]
    # the saved signals against another filter set, as `hinf worst --replay`: the same replay.h5
    replay = hinf.replay_worst(cfg, report["file"], str(tmp_path / "lib_replay"), filters="ukf,dnn",
                               network=ckpt, modes="measured")
    args = [hinf_cli(), "worst", VANDERPOL, "--filters", "ukf,dnn", "--network", ckpt, "--mode", "measured",
            "--replay", report["file"], "--quiet", "--out", str(tmp_path / "cli_replay")]
    for s in SMALL:
        args += ["--set", s]
    subprocess.run(args, check=True, capture_output=True)
    same_results(hinf.read_results(replay["file"]), hinf.read_results(str(tmp_path / "cli_replay" / "replay.h5")))
    assert replay["sets"] == ["dnn_gain_measured", "ekf"] and replay["filters"] == ["ukf", "dnn_gain_measured"]
    assert replay["ratio"].shape == (2, 2) and replay["diverged"].shape == (2, 2) and replay["steps"] == 300
    assert replay["ratio"][0, 1] == report["filters"][0]["ratio"]  # the DNN filter under its own worst signals
    with pytest.raises(hinf.Error, match="energy must be"):
        hinf.worst(cfg, str(tmp_path / "bad"), filters="ekf", energy=-1.0)
    # the checks it shares with the program name the library's arguments, not the program's flags
    with pytest.raises(hinf.Error, match=r"^evals must be >= 1 \(got 0\)") as err:
        hinf.worst(cfg, str(tmp_path / "bad"), filters="ekf", evals=0)
    assert "--" not in str(err.value)
    with pytest.raises(hinf.Error, match=r"^modes 'bogus' is not one of: oracle, measured") as err:
        hinf.worst(cfg, str(tmp_path / "bad"), filters="dnn", network=ckpt, modes="bogus")
    assert "--" not in str(err.value)


def test_train_names_the_states_the_outputs_do_not_see(tmp_path, capfd):
    """The library's train says what `hinf train` says first (the DC motor's current, docs/method.md 16.18)."""
    cfg = hinf.Config(os.path.join(ROOT, "examples", "systems", "dc_motor.toml"), set=SMALL)
    hinf.train(cfg, str(tmp_path / "run"), until=0.02)
    assert "the outputs tell next to nothing about" in capfd.readouterr().err


def test_gain_run_reports_its_selection_and_acceptance(tmp_path):
    """A gain run to t_final keeps best.h5 and judges it, as `hinf train` does (docs/method.md 16.5, 16.9)."""
    cfg = hinf.Config(VANDERPOL, set=SMALL + ["filter.t_final=0.3", "training.checkpoint_every=10",
                                              "training.select_runs=2"])
    report = hinf.train(cfg, str(tmp_path / "run"))
    assert report["best_checkpoint"] == str(tmp_path / "run" / "best.h5")
    assert os.path.exists(report["best_checkpoint"])
    assert report["best_step"] > 0 and report["best_step"] % 10 == 0
    assert report["knot_runaway_step"] == -1 and report["knot_runaway_knot"] == -1
    assert math.isfinite(report["acceptance_rmse_settled"]) and report["acceptance_rmse_settled_ekf"] > 0
    assert math.isfinite(report["acceptance_rms_q_settled"]) and report["acceptance_rms_q_settled_ekf"] > 0
    assert report["acceptance"] in ("pass", "fail")
    assert report["acceptance_checkpoint"] == report["best_checkpoint"]
    assert report["acceptance_line"].startswith("acceptance (")
    # what to try is given after a fail, and only then
    assert (report["acceptance_advice"] is not None) == (report["acceptance"] == "fail")
    # a level to try after a pass far behind the EKF on the check's runs, and only then (method 16.12)
    behind = (report["acceptance_rmse_settled"] > 1.25 * report["acceptance_rmse_settled_ekf"]
              or report["acceptance_rms_q_settled"] > 1.25 * report["acceptance_rms_q_settled_ekf"])
    assert (report["acceptance_note"] is not None) == (report["acceptance"] == "pass" and behind)
    # the settled window's note: None or the line hinf train prints (docs/compare.md, "Settled")
    note = report["acceptance_settle_note"]
    assert note is None or note.startswith("acceptance: note: the EKF's error is still falling")
    # stopped before t_final: no check
    early = hinf.train(cfg, str(tmp_path / "early"), until=0.1)
    assert early["acceptance"] is None


def test_rho_and_its_bound_match_hinf_rho():
    """The level a config trains at and the linearised game's smallest level, as `hinf rho` prints them (method 16.12)."""
    cfg = hinf.Config(VANDERPOL)
    assert cfg.rho == 0.5  # named in the config
    out = subprocess.run([hinf_cli(), "rho", VANDERPOL], capture_output=True, text=True, check=True).stdout
    assert out.startswith("rho* = %.4g:" % cfg.rho_bound)
    assert 1.3 < cfg.rho_bound < 1.5  # 1.38 as dt -> 0 (scripts/vdp-rho-bound)
    text = open(VANDERPOL).read().replace("rho = 0.5", "")
    own = hinf.Config.from_text(text, "no_rho.toml")
    assert own.rho == 1.25 * own.rho_bound  # a config naming no rho: 1.25 rho*
    # Van der Pol's game settles within its horizon: no higher level where the run goes on (hinf rho says so)
    assert cfg.rho_run_on == cfg.rho_bound
    assert "rho*_on = rho*:" in out
    motor = hinf.Config(os.path.join(ROOT, "examples", "systems", "dc_motor.toml"))
    assert 0.96 < motor.rho_run_on < 1.0 and motor.rho_bound < 0.7  # the encoder's angle: slow noise passes at gain 1
    assert "rho = " in own.text  # written into the effective config


def test_constant_storage_violation_matches_hinf_rho():
    """A discrete system's constant-storage verdict, as `hinf rho` prints it (method 16.8)."""
    turn_path = os.path.join(ROOT, "examples", "systems", "coordinated_turn.toml")
    turn = hinf.Config(turn_path)
    assert turn.constant_storage_violation > 0.05  # none exists: an error in the turn rate turns with the heading
    out = subprocess.run([hinf_cli(), "rho", turn_path], capture_output=True, text=True, check=True).stdout
    assert "no constant storage" in out
    assert hinf.Config(os.path.join(ROOT, "examples", "systems", "radar.toml")).constant_storage_violation <= 0
    assert math.isnan(hinf.Config(VANDERPOL).constant_storage_violation)  # continuous time: nothing to check


def test_unseen_share_matches_hinf_rho():
    """The states the outputs tell next to nothing about, as `hinf rho` names them (method 16.18)."""
    motor_path = os.path.join(ROOT, "examples", "systems", "dc_motor.toml")
    share = hinf.Config(motor_path).unseen_share
    assert len(share) == 3 and share[0] < 0.1 and share[2] >= 0.9  # the encoder; the current, masked
    out = subprocess.run([hinf_cli(), "rho", motor_path], capture_output=True, text=True, check=True).stdout
    assert "the outputs tell next to nothing about cur" in out
    assert max(hinf.Config(VANDERPOL).unseen_share) < 0.1


def test_ensemble_of_copies_is_the_network(trained, record):
    """ensemble=True: one dnn filter with the mean gain; two copies of one network filter as that network, bit for bit,
    and one network alone is refused in hinf's one line."""
    cfg, ckpt, _, _, _ = trained
    t, Y, _ = record
    one = hinf.Filter(cfg, "dnn", network=ckpt).run(t, Y)
    two = hinf.Filter(cfg, "dnn", network=[ckpt, ckpt], ensemble=True)
    assert two.name == "dnn_gain_ensemble"
    assert np.array_equal(two.run(t, Y).xhat, one.xhat)
    with pytest.raises(hinf.Error, match="two or more networks"):
        hinf.Filter(cfg, "dnn", network=ckpt, ensemble=True)


def test_export_c_writes_what_hinf_export_writes(trained, tmp_path):
    """hinf.export_c: the same files as `hinf export`; an ensemble of two copies compiles as C99 with -Werror; several
    checkpoints without ensemble=True raise hinf.Error in one line."""
    _, ckpt, _, _, _ = trained
    r = hinf.export_c(ckpt, str(tmp_path / "py"))
    assert r["networks"] == 1 and r["variant"] == "gain" and r["parameters"] > 0
    assert r["files"] == [str(tmp_path / "py" / "hinf_filter.h"), str(tmp_path / "py" / "hinf_filter.c")]
    subprocess.run([hinf_cli(), "export", ckpt, "--c", str(tmp_path / "cli")], check=True, capture_output=True)
    for name in ("hinf_filter.h", "hinf_filter.c"):
        with open(tmp_path / "py" / name) as a, open(tmp_path / "cli" / name) as b:
            assert a.read() == b.read()
    e = hinf.export_c([ckpt, ckpt], str(tmp_path / "ens"), name="vdp_ens", ensemble=True)
    assert e["networks"] == 2 and e["parameters"] == 2 * r["parameters"]
    cc = shutil.which("cc")
    if cc:
        subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-c",
                        str(tmp_path / "ens" / "vdp_ens.c"), "-o", str(tmp_path / "ens" / "vdp_ens.o")], check=True)
    one_line_error(lambda: hinf.export_c([ckpt, ckpt], str(tmp_path / "bad")), "ensemble=True")


def test_known_inputs_are_read_as_f_reads_them(tmp_path):
    """[system] inputs (docs/byos.md "Known inputs"): the names, u(t) held between rows, the Euler step driven by it,
    and the effective config carrying the table (it loads again without the file)."""
    motor = hinf.Config(os.path.join(ROOT, "examples", "systems", "dc_motor_recorded.toml"))
    assert motor.input_names == ["V"]
    assert motor.inputs_at(1.5).tolist() == [-6.3]  # the row at t = 1 s, held
    step = motor.advance(np.zeros(3), t=1.5)
    assert step[2] == pytest.approx(motor.dt * -6.3 / 0.5, rel=1e-15)  # the current: dt V / L from rest
    again = hinf.Config.from_text(motor.text, name=str(tmp_path / "elsewhere.toml"))
    assert again.inputs_at(1.5).tolist() == [-6.3]
    assert hinf.Config(VANDERPOL).input_names == []
    # another run's inputs in place of the table (a record's): u(t) follows them, the config itself is unchanged
    rec = motor.with_inputs(np.array([0.5, 1.0, 1.5]), np.array([[3.0], [4.0], [5.0]]))
    assert rec.inputs_at(1.2).tolist() == [4.0]
    assert motor.with_inputs(np.array([0.5, 1.0]), np.array([7.0, 8.0])).inputs_at(2.0).tolist() == [8.0]
    assert motor.inputs_at(1.5).tolist() == [-6.3]
    one_line_error(lambda: motor.with_inputs(np.array([0.5, 1.0]), np.zeros((2, 2))), "expected (2, 1)")
