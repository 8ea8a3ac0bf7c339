// The Python binding hinf._hinf (pybind11) of the public facade include/hinf/hinf.hpp: configs, networks, filters
// (NumPy arrays in and out), training with a progress callback. hinf::Error becomes the Python exception
// hinf.Error with the same one-line message. Not the result-file readers (python/hinf/__init__.py, h5py).
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <sstream>

#include "hinf/hinf.hpp"

namespace py = pybind11;

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::string shape_text(const Array& a) {
    std::ostringstream os;
    os << "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) os << (i ? ", " : "") << a.shape(i);
    os << (a.ndim() == 1 ? ",)" : ")");
    return os.str();
}

// A 1-d array of `want` values (a [1 x want] or [want x 1] row or column too), as a vector.
std::vector<double> vector_of(const Array& a, std::size_t want, const std::string& what) {
    HINF_CHECK(std::size_t(a.size()) == want && a.ndim() <= 2,
               what + " has shape " + shape_text(a) + "; expected " + std::to_string(want) + " values");
    return std::vector<double>(a.data(), a.data() + a.size());
}

// A new NumPy array holding a copy of v (small results: estimates, states).
Array to_array(const std::vector<double>& v) { return Array(py::ssize_t(v.size()), v.data()); }

// A NumPy view of a vector owned by the Python object `owner` (no copy).
py::array view(std::vector<double>& v, std::vector<py::ssize_t> shape, py::handle owner) {
    return py::array_t<double>(shape, v.data(), owner);
}

hinf::FilterOptions filter_options(const py::object& network, double dt, const py::object& initial_estimate,
                                   const py::object& initial_std, std::int64_t particles, double roughening,
                                   int glf_vertices, bool ensemble, int n) {
    hinf::FilterOptions o;
    o.ensemble = ensemble;
    auto one_network = [](const py::handle& h) {
        if (py::isinstance<py::str>(h)) return hinf::TrainedNetwork::load(h.cast<std::string>());
        return h.cast<hinf::TrainedNetwork>();
    };
    if (!network.is_none()) {
        if (py::isinstance<py::str>(network) || py::isinstance<hinf::TrainedNetwork>(network))
            o.networks.push_back(one_network(network));
        else
            for (const py::handle& h : network) o.networks.push_back(one_network(h));
    }
    o.dt = dt;
    if (!initial_estimate.is_none())
        o.initial_estimate = vector_of(initial_estimate.cast<Array>(), std::size_t(n), "initial_estimate");
    if (!initial_std.is_none()) o.initial_std = vector_of(initial_std.cast<Array>(), std::size_t(n), "initial_std");
    o.particles = particles;
    o.roughening = roughening;
    o.glf_vertices = glf_vertices;
    return o;
}

// train/resume settings; the callback runs with the GIL held and lets Ctrl-C through
hinf::TrainSettings train_settings(const std::string& out, double until, const py::object& progress, bool quiet,
                                   bool force, int threads) {
    hinf::TrainSettings s;
    s.out_dir = out;
    s.until = until;
    s.quiet = quiet;
    s.force = force;
    s.threads = threads;
    if (!progress.is_none()) {
        // the training copies the callback without the GIL: hold the Python object behind a shared_ptr whose
        // last owner takes the GIL to release it
        std::shared_ptr<py::object> cb(new py::object(progress), [](py::object* o) {
            py::gil_scoped_acquire gil;
            delete o;
        });
        s.on_progress = [cb](const hinf::TrainProgress& p) {
            py::gil_scoped_acquire gil;
            if (PyErr_CheckSignals() != 0) throw py::error_already_set();
            (*cb)(p);
        };
    }
    return s;
}

py::dict report_dict(const hinf::TrainReport& r) {
    py::dict d;
    d["diverged"] = r.diverged;
    d["first_step"] = r.first_step;
    d["last_step"] = r.last_step;
    d["wall_seconds"] = r.wall_seconds;
    d["final_loss"] = r.final_loss;
    d["median_rel_residual"] = r.median_rel_residual;
    d["fraction_steps_violation_ok"] = r.fraction_steps_violation_ok;
    d["mean_cosine"] = r.mean_cosine;
    d["checkpoint"] = r.checkpoint;
    d["best_checkpoint"] = r.best_checkpoint.empty() ? py::object(py::none()) : py::object(py::str(r.best_checkpoint));
    d["best_step"] = r.best_step;
    d["acceptance"] = r.acceptance.empty() ? py::object(py::none()) : py::object(py::str(r.acceptance));
    d["acceptance_checkpoint"] = r.acceptance_checkpoint;
    d["acceptance_line"] = r.acceptance_line;
    d["acceptance_advice"] = r.acceptance_advice.empty() ? py::object(py::none()) : py::object(py::str(r.acceptance_advice));
    d["acceptance_note"] = r.acceptance_note.empty() ? py::object(py::none()) : py::object(py::str(r.acceptance_note));
    d["acceptance_selection_note"] = r.acceptance_selection_note.empty()
                                         ? py::object(py::none())
                                         : py::object(py::str(r.acceptance_selection_note));
    d["acceptance_settle_note"] =
        r.acceptance_settle_note.empty() ? py::object(py::none()) : py::object(py::str(r.acceptance_settle_note));
    d["acceptance_rmse_settled"] = r.acceptance_rmse_settled;
    d["acceptance_rmse_settled_ekf"] = r.acceptance_rmse_settled_ekf;
    d["acceptance_rms_q_settled"] = r.acceptance_rms_q_settled;
    d["acceptance_rms_q_settled_ekf"] = r.acceptance_rms_q_settled_ekf;
    d["knot_runaway_step"] = r.knot_runaway_step;
    d["knot_runaway_knot"] = r.knot_runaway_knot;
    return d;
}

// compare's and worst's output directory, filter set (as hinf.filters takes it) and threads
template <class Settings>
void simulation_settings(Settings& st, const hinf::Config& cfg, const std::string& out, const std::string& filters,
                         const py::object& network, const std::string& modes, bool ensemble, std::int64_t particles,
                         double roughening, int glf_vertices, bool quiet, int threads) {
    st.out_dir = out;
    st.filters = filters;
    st.networks = filter_options(network, 0.0, py::none(), py::none(), particles, roughening, glf_vertices, ensemble,
                                 cfg.states())
                      .networks;
    st.modes = modes;
    st.ensemble = ensemble;
    st.particles = particles;
    st.roughening = roughening;
    st.glf_vertices = glf_vertices;
    st.quiet = quiet;
    st.threads = threads;
}

}  // namespace

PYBIND11_MODULE(_hinf, m) {
    m.doc() = "hinf: H-infinity HJIE-trained DNN filters and their baselines (docs/python.md)";
    py::register_exception<hinf::Error>(m, "Error", PyExc_RuntimeError);
    m.def("version", &hinf::version);

    py::class_<hinf::Config>(m, "Config", "A checked run config (TOML; keys: docs/formats.md)")
        .def(py::init([](const std::string& path, const std::vector<std::string>& set) {
                 return hinf::Config::load(path, set);
             }),
             py::arg("path"), py::arg("set") = std::vector<std::string>{},
             "Reads and checks a config; set: overrides such as ['training.seed=3']")
        .def_static("from_text", &hinf::Config::from_text, py::arg("toml"), py::arg("name") = "<text>",
                    py::arg("set") = std::vector<std::string>{})
        .def_property_readonly("states", &hinf::Config::states)
        .def_property_readonly("outputs", &hinf::Config::outputs)
        .def_property_readonly("disturbances", &hinf::Config::disturbances)
        .def_property_readonly("dt", &hinf::Config::dt)
        .def_property_readonly("t_final", &hinf::Config::t_final)
        .def_property_readonly("rho", &hinf::Config::rho)
        .def_property_readonly("rho_bound", &hinf::Config::rho_bound)
        .def_property_readonly("rho_run_on", &hinf::Config::rho_run_on)
        .def_property_readonly("constant_storage_violation", &hinf::Config::constant_storage_violation)
        .def_property_readonly("unseen_share", &hinf::Config::unseen_share)
        .def_property_readonly("system", &hinf::Config::system)
        .def_property_readonly("state_names", &hinf::Config::state_names)
        .def_property_readonly("state_units", &hinf::Config::state_units)
        .def_property_readonly("input_names", &hinf::Config::input_names)
        .def(
            "inputs_at", [](const hinf::Config& c, double t) { return to_array(c.inputs_at(t)); }, py::arg("t"),
            "u(t): the known inputs' values at t ([system] inputs), held or interpolated as f, g, h read them")
        .def(
            "with_inputs",
            [](const hinf::Config& c, const Array& t, const Array& u) {
                const py::ssize_t q = py::ssize_t(c.input_names().size());
                HINF_CHECK(t.ndim() == 1, "with_inputs: t has shape " + shape_text(t) + "; expected (R,), one time per row");
                const py::ssize_t R = t.shape(0);
                const bool ok = (u.ndim() == 2 && u.shape(0) == R && u.shape(1) == q) ||
                                (q == 1 && u.ndim() == 1 && u.shape(0) == R);
                HINF_CHECK(q == 0 || ok, "with_inputs: u has shape " + shape_text(u) + "; expected (" + std::to_string(R) +
                                             ", " + std::to_string(q) + "): one row per time, one column per input (" +
                                             "input_names' order)");
                return c.with_inputs(std::vector<double>(t.data(), t.data() + R),
                                     std::vector<double>(u.data(), u.data() + u.size()));
            },
            py::arg("t"), py::arg("u"),
            "This config with another run's known inputs (a record's) in place of its table: t (R,), u (R, inputs)")
        .def_property_readonly("initial_state", [](const hinf::Config& c) { return to_array(c.initial_state()); })
        .def_property_readonly("initial_estimate",
                               [](const hinf::Config& c) { return to_array(c.initial_estimate()); })
        .def_property_readonly("text", &hinf::Config::text)
        .def(
            "measure",
            [](const hinf::Config& c, const Array& x, double t) {
                return to_array(c.measure(vector_of(x, std::size_t(c.states()), "measure: x"), t));
            },
            py::arg("x"), py::arg("t") = 0.0, "y = C(x, t) without noise")
        .def(
            "advance",
            [](const hinf::Config& c, const Array& x, const py::object& v, double t, double dt) {
                std::vector<double> vv;
                if (!v.is_none()) vv = vector_of(v.cast<Array>(), std::size_t(c.disturbances()), "advance: v");
                return to_array(c.advance(vector_of(x, std::size_t(c.states()), "advance: x"), vv, t,
                                                dt > 0 ? dt : c.dt()));
            },
            py::arg("x"), py::arg("v") = py::none(), py::arg("t") = 0.0, py::arg("dt") = 0.0,
            "x + dt (A(x, t) + B(x, t) v): the Euler step of the truth and every filter (dt 0: the config's)")
        .def("__repr__", [](const hinf::Config& c) {
            return "<hinf.Config system=" + c.system() + " n=" + std::to_string(c.states()) +
                   " m=" + std::to_string(c.outputs()) + ">";
        });

    py::class_<hinf::TrainedNetwork>(m, "Network", "A trained network, frozen, from DIR/checkpoint.h5")
        .def(py::init(&hinf::TrainedNetwork::load), py::arg("checkpoint"))
        .def_property_readonly("path", &hinf::TrainedNetwork::path)
        .def_property_readonly("config", &hinf::TrainedNetwork::config)
        .def_property_readonly("variant", &hinf::TrainedNetwork::variant)
        .def_property_readonly("precision", &hinf::TrainedNetwork::precision)
        .def(
            "gradient",
            [](const hinf::TrainedNetwork& net, const Array& xt) {
                const int n = net.config().states();
                HINF_CHECK((xt.ndim() == 1 && xt.shape(0) == n) || (xt.ndim() == 2 && xt.shape(1) == n),
                           "Network.gradient: x~ has shape " + shape_text(xt) + "; expected (" + std::to_string(n) +
                               ",) or (count, " + std::to_string(n) + ")");
                std::vector<double> p = net.gradient(std::vector<double>(xt.data(), xt.data() + xt.size()));
                Array out = to_array(p);
                if (xt.ndim() == 1) return py::object(out);
                return py::object(out.reshape({xt.shape(0), py::ssize_t(n)}));
            },
            py::arg("xtilde"), "p = dV/dx~ at x~ ([n] or [count x n])")
        .def(
            "value",
            [](const hinf::TrainedNetwork& net, const Array& xt) {
                return net.value(vector_of(xt, std::size_t(net.config().states()), "Network.value: x~"));
            },
            py::arg("xtilde"))
        .def(
            "gain",
            [](const hinf::TrainedNetwork& net, const Array& xh, double t) {
                const int n = net.config().states(), m = net.config().outputs();
                HINF_CHECK((xh.ndim() == 1 && xh.shape(0) == n) || (xh.ndim() == 2 && xh.shape(1) == n),
                           "Network.gain: x^ has shape " + shape_text(xh) + "; expected (" + std::to_string(n) +
                               ",) or (count, " + std::to_string(n) + ")");
                std::vector<double> K = net.gain(std::vector<double>(xh.data(), xh.data() + xh.size()), t);
                Array out = to_array(K);
                if (xh.ndim() == 1) return py::object(out.reshape({py::ssize_t(n), py::ssize_t(m)}));
                return py::object(out.reshape({xh.shape(0), py::ssize_t(n), py::ssize_t(m)}));
            },
            py::arg("xhat"), py::arg("t") = 0.0,
            "variant gain: K(x^, t) [n x m] at x^ ([n]; [count x n] gives [count x n x m])");

    py::class_<hinf::FilterTrace>(m, "FilterTrace",
                                  "One filter over a record: xhat [K x n] (row k estimates x(t_k) from y before t_k), "
                                  "covariance [K x n x n] or None, innovation [K x m], xhat_final [n], diverged_at")
        .def_readonly("name", &hinf::FilterTrace::name)
        .def_readonly("steps", &hinf::FilterTrace::steps)
        .def_readonly("diverged_at", &hinf::FilterTrace::diverged_at)
        .def_property_readonly("xhat",
                               [](py::object self) {
                                   auto& t = self.cast<hinf::FilterTrace&>();
                                   return view(t.xhat, {py::ssize_t(t.steps), t.n}, self);
                               })
        .def_property_readonly("covariance",
                               [](py::object self) -> py::object {
                                   auto& t = self.cast<hinf::FilterTrace&>();
                                   if (t.covariance.empty()) return py::none();
                                   return view(t.covariance, {py::ssize_t(t.steps), t.n, t.n}, self);
                               })
        .def_property_readonly("innovation",
                               [](py::object self) {
                                   auto& t = self.cast<hinf::FilterTrace&>();
                                   return view(t.innovation, {py::ssize_t(t.steps), t.m}, self);
                               })
        .def_property_readonly("xhat_final",
                               [](py::object self) {
                                   auto& t = self.cast<hinf::FilterTrace&>();
                                   return view(t.xhat_final, {py::ssize_t(t.n)}, self);
                               })
        .def_property_readonly("innovation_rms", [](const hinf::FilterTrace& t) { return to_array(t.innovation_rms); })
        .def_property_readonly("innovation_mean", [](const hinf::FilterTrace& t) { return to_array(t.innovation_mean); })
        .def_property_readonly("nis",
                               [](py::object self) -> py::object {
                                   auto& t = self.cast<hinf::FilterTrace&>();
                                   if (t.nis.empty()) return py::none();
                                   return view(t.nis, {py::ssize_t(t.steps)}, self);
                               })
        .def_readonly("nis_per_output", &hinf::FilterTrace::nis_per_output,
                      "Mean normalised innovation squared per output from t_0 + settle_time: about 1 where the "
                      "filter's statistics hold for the record (NaN: the filter states no innovation covariance)")
        .def_readonly("note", &hinf::FilterTrace::note,
                      "What the filter met on the record that the arrays do not say, or '' (a DNN gain filter: its "
                      "estimate went far beyond the region its network was trained on)")
        .def("__repr__", [](const hinf::FilterTrace& t) {
            return "<hinf.FilterTrace " + t.name + " steps=" + std::to_string(t.steps) +
                   (t.diverged_at >= 0 ? " diverged" : "") + ">";
        });

    auto make_filter = [](const hinf::Config& cfg, const std::string& name, const py::object& network, double dt,
                          const py::object& x0, const py::object& sd, std::int64_t particles, double roughening,
                          int glf_vertices, bool ensemble) {
        return hinf::Filter::create(cfg, name,
                                    filter_options(network, dt, x0, sd, particles, roughening, glf_vertices, ensemble,
                                                   cfg.states()));
    };
    py::class_<hinf::Filter>(m, "Filter", "An on-line filter: dnn (measured mode), ekf, ukf, pf, ehf, glf or open_loop")
        .def(py::init(make_filter), py::arg("config"), py::arg("name"), py::arg("network") = py::none(),
             py::arg("dt") = 0.0, py::arg("initial_estimate") = py::none(), py::arg("initial_std") = py::none(),
             py::arg("particles") = 2000, py::arg("roughening") = 0.0, py::arg("glf_vertices") = 8,
             py::arg("ensemble") = false)
        .def_property_readonly("name", &hinf::Filter::name)
        .def_property_readonly("states", &hinf::Filter::states)
        .def_property_readonly("outputs", &hinf::Filter::outputs)
        .def_property_readonly("dt", &hinf::Filter::dt)
        .def_property_readonly("has_covariance", &hinf::Filter::has_covariance)
        .def_property_readonly("diverged", &hinf::Filter::diverged)
        .def("reset", &hinf::Filter::reset)
        .def(
            "step",
            [](hinf::Filter& f, const Array& y, double t) {
                return f.step(vector_of(y, std::size_t(f.outputs()), "Filter.step: y"), t);
            },
            py::arg("y"), py::arg("t"),
            "Consumes y(t_k); then estimate is the estimate of x(t_k + dt). False once the filter diverged.")
        .def_property_readonly("estimate", [](const hinf::Filter& f) { return to_array(f.estimate()); })
        .def_property_readonly("covariance",
                               [](const hinf::Filter& f) -> py::object {
                                   std::vector<double> P = f.covariance();
                                   if (P.empty()) return py::none();
                                   return to_array(P).reshape({f.states(), f.states()});
                               })
        .def(
            "run",
            [](const hinf::Filter& f, const Array& t, const Array& y) {
                const int m = f.outputs();
                HINF_CHECK(t.ndim() == 1, "Filter.run: t has shape " + shape_text(t) + "; expected (K,), one time per row");
                const py::ssize_t K = t.shape(0);
                const bool ok = (y.ndim() == 2 && y.shape(0) == K && y.shape(1) == m) ||
                                (m == 1 && y.ndim() == 1 && y.shape(0) == K);
                HINF_CHECK(ok, "Filter.run: y has shape " + shape_text(y) + "; expected (" + std::to_string(K) + ", " +
                                   std::to_string(m) + "): one row per time, one column per output");
                py::gil_scoped_release nogil;
                return f.run(t.data(), y.data(), std::int64_t(K));
            },
            py::arg("t"), py::arg("y"),
            "Runs a fresh copy over a record t [K], y [K x m] exactly as `hinf filter` does; returns a FilterTrace")
        .def("__repr__", [](const hinf::Filter& f) { return "<hinf.Filter " + f.name() + ">"; });

    m.def(
        "filters",
        [](const hinf::Config& cfg, const std::string& names, const py::object& network, double dt, const py::object& x0,
           const py::object& sd, std::int64_t particles, double roughening, int glf_vertices, bool ensemble) {
            return hinf::Filter::create_all(cfg, names,
                                            filter_options(network, dt, x0, sd, particles, roughening, glf_vertices,
                                                           ensemble, cfg.states()));
        },
        py::arg("config"), py::arg("names"), py::arg("network") = py::none(), py::arg("dt") = 0.0,
        py::arg("initial_estimate") = py::none(), py::arg("initial_std") = py::none(), py::arg("particles") = 2000,
        py::arg("roughening") = 0.0, py::arg("glf_vertices") = 8, py::arg("ensemble") = false,
        "Every filter of a comma list ('dnn,ekf,ukf'), dnn once per network (or once, with the mean gain of all of "
        "them, where ensemble=True), in the order `hinf filter` uses");
    m.def("filter_names", &hinf::Filter::names);

    py::class_<hinf::TrainProgress>(m, "TrainProgress", "One finished time step of training")
        .def_readonly("step", &hinf::TrainProgress::step)
        .def_readonly("last_step", &hinf::TrainProgress::last_step)
        .def_readonly("t", &hinf::TrainProgress::t)
        .def_readonly("loss_first", &hinf::TrainProgress::loss_first)
        .def_readonly("loss_last", &hinf::TrainProgress::loss_last)
        .def_readonly("rel_residual", &hinf::TrainProgress::rel_residual)
        .def_readonly("violation", &hinf::TrainProgress::violation)
        .def("__repr__", [](const hinf::TrainProgress& p) {
            return "<hinf.TrainProgress step " + std::to_string(p.step) + "/" + std::to_string(p.last_step) + ">";
        });

    m.def(
        "export_c",
        [](const py::object& checkpoints, const std::string& dir, const std::string& name, bool ensemble) {
            std::vector<std::string> paths;
            if (py::isinstance<py::str>(checkpoints)) paths.push_back(checkpoints.cast<std::string>());
            else paths = checkpoints.cast<std::vector<std::string>>();
            hinf::ExportReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::export_c99(paths, dir, name, ensemble);
            }
            py::dict d;
            d["files"] = r.files;
            d["parameters"] = r.parameters;
            d["weight_bytes"] = r.weight_bytes;
            d["flops_per_step"] = r.flops_per_step;
            d["networks"] = r.networks;
            d["variant"] = r.variant;
            d["precision"] = r.precision;
            d["system"] = r.system;
            return d;
        },
        py::arg("checkpoints"), py::arg("dir"), py::arg("name") = "hinf_filter", py::arg("ensemble") = false,
        "Writes a trained filter as dependency-free C99, dir/name.h and dir/name.c (as `hinf export`): one checkpoint "
        "path, or a list of gain networks with ensemble=True (their mean gain)");
    m.def(
        "compare",
        [](const hinf::Config& cfg, const std::string& out, const std::string& filters, const py::object& network,
           const std::string& modes, bool ensemble, std::int64_t runs, const std::string& scenario, double until,
           std::int64_t particles, double roughening, int glf_vertices, bool quiet, int threads) {
            hinf::CompareSettings st;
            simulation_settings(st, cfg, out, filters, network, modes, ensemble, particles, roughening, glf_vertices,
                                quiet, threads);
            st.runs = runs;
            st.scenario = scenario;
            st.until = until;
            hinf::CompareReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::compare(cfg, st);
            }
            py::dict d;
            d["scenario"] = r.scenario;
            d["file"] = r.file;
            d["runs"] = r.runs;
            d["steps"] = r.steps;
            d["truth_escaped_runs"] = r.truth_escaped_runs;
            d["streams_identical"] = r.streams_identical;
            d["wall_seconds"] = r.wall_seconds;
            py::list rows;
            for (const hinf::CompareRow& f : r.filters) {
                py::dict row;
                row["name"] = f.name;
                row["mode"] = f.mode;
                row["diverged_runs"] = f.diverged_runs;
                row["rmse_position"] = f.rmse_position;
                row["rmse_position_settled"] = f.rmse_position_settled;
                row["rmse_velocity"] = f.rmse_velocity;
                row["rmse_velocity_settled"] = f.rmse_velocity_settled;
                row["attenuation_ratio"] = f.attenuation_ratio;
                row["mse_db"] = f.mse_db;
                row["mse_filtered_db"] = f.mse_filtered_db;
                row["us_per_step"] = f.us_per_step;
                row["nees_per_state"] = f.nees_per_state;
                rows.append(row);
            }
            d["filters"] = rows;
            return d;
        },
        py::arg("config"), py::arg("out"), py::arg("filters") = "dnn,ekf,ukf,pf,open_loop",
        py::arg("network") = py::none(), py::arg("modes") = "oracle,measured", py::arg("ensemble") = false,
        py::arg("runs") = 50, py::arg("scenario") = "nominal", py::arg("until") = -1.0, py::arg("particles") = 2000,
        py::arg("roughening") = 0.0, py::arg("glf_vertices") = 8, py::arg("quiet") = true, py::arg("threads") = 0,
        "Runs `hinf compare` on the config (the same runs, bits and files: out/compare.h5, out/compare.csv); returns "
        "its table as a dict, one dict per filter in 'filters' (hinf.read(out + '/compare.h5') has the rest)");
    m.def(
        "worst",
        [](const hinf::Config& cfg, const std::string& out, const std::string& filters, const py::object& network,
           const std::string& modes, bool ensemble, const py::object& energy, double until, int evals,
           int random_starts, int linear_pieces, bool keep_initial_error, std::int64_t particles, double roughening,
           int glf_vertices, bool quiet, int threads) {
            hinf::WorstSettings st;
            simulation_settings(st, cfg, out, filters, network, modes, ensemble, particles, roughening, glf_vertices,
                                quiet, threads);
            if (!energy.is_none()) st.energy = energy.cast<double>();
            st.until = until;
            st.evals = evals;
            st.random_starts = random_starts;
            st.linear_pieces = linear_pieces;
            st.keep_initial_error = keep_initial_error;
            hinf::WorstReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::worst(cfg, st);
            }
            py::dict d;
            d["file"] = r.file;
            d["energy"] = r.energy;
            d["steps"] = r.steps;
            d["wall_seconds"] = r.wall_seconds;
            py::list rows;
            for (const hinf::WorstRow& f : r.filters) {
                py::dict row;
                row["name"] = f.name;
                row["ratio"] = f.ratio;
                row["small_signal"] = f.small_signal;
                row["diverged"] = f.diverged;
                row["found_from"] = f.found_from;
                rows.append(row);
            }
            d["filters"] = rows;
            return d;
        },
        py::arg("config"), py::arg("out"), py::arg("filters") = "dnn,ekf,ukf,pf,open_loop",
        py::arg("network") = py::none(), py::arg("modes") = "oracle,measured", py::arg("ensemble") = false,
        py::arg("energy") = py::none(), py::arg("until") = -1.0, py::arg("evals") = 200, py::arg("random_starts") = 4,
        py::arg("linear_pieces") = 20, py::arg("keep_initial_error") = false, py::arg("particles") = 2000,
        py::arg("roughening") = 0.0, py::arg("glf_vertices") = 8, py::arg("quiet") = true, py::arg("threads") = 0,
        "Runs `hinf worst`'s search on the config (the same starts, bits and out/worst.h5); returns each filter's worst "
        "ratio found, its small-signal ratio and where it was found, one dict per filter in 'filters'");
    m.def(
        "replay_worst",
        [](const hinf::Config& cfg, const std::string& worst_file, const std::string& out, const std::string& filters,
           const py::object& network, const std::string& modes, bool ensemble, std::int64_t particles,
           double roughening, int glf_vertices, bool quiet, int threads) {
            hinf::WorstSettings st;
            simulation_settings(st, cfg, out, filters, network, modes, ensemble, particles, roughening, glf_vertices,
                                quiet, threads);
            hinf::ReplayReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::replay_worst(cfg, worst_file, st);
            }
            const py::ssize_t D = py::ssize_t(r.sets.size()), F = py::ssize_t(r.filters.size());
            py::array_t<double> ratio({D, F});
            py::array_t<bool> diverged({D, F});
            for (py::ssize_t i = 0; i < D * F; ++i) {
                ratio.mutable_data()[i] = r.ratio[std::size_t(i)];
                diverged.mutable_data()[i] = r.diverged[std::size_t(i)];
            }
            py::dict d;
            d["file"] = r.file;
            d["steps"] = r.steps;
            d["keep_initial_error"] = r.keep_initial_error;
            d["sets"] = r.sets;
            d["energy"] = r.energy;
            d["filters"] = r.filters;
            d["ratio"] = ratio;
            d["diverged"] = diverged;
            return d;
        },
        py::arg("config"), py::arg("worst_file"), py::arg("out"), py::arg("filters") = "dnn,ekf,ukf,pf,open_loop",
        py::arg("network") = py::none(), py::arg("modes") = "oracle,measured", py::arg("ensemble") = false,
        py::arg("particles") = 2000, py::arg("roughening") = 0.0, py::arg("glf_vertices") = 8, py::arg("quiet") = true,
        py::arg("threads") = 0,
        "Runs the signal sets a search saved (worst_file: a worst.h5 of hinf.worst or `hinf worst`) against the filters, "
        "as `hinf worst CONFIG --replay worst_file` (the same bits and out/replay.h5); returns 'sets' [D] (the filter "
        "each set was found for), 'filters' [F], 'ratio' and 'diverged' [D x F] arrays, 'energy' [D]");
    m.def(
        "train",
        [](const hinf::Config& cfg, const std::string& out, double until, const py::object& progress, bool quiet,
           bool force, int threads) {
            hinf::TrainSettings s = train_settings(out, until, progress, quiet, force, threads);
            hinf::TrainReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::train(cfg, s);
            }
            return report_dict(r);
        },
        py::arg("config"), py::arg("out"), py::arg("until") = -1.0, py::arg("progress") = py::none(),
        py::arg("quiet") = true, py::arg("force") = false, py::arg("threads") = 0,
        "Trains a network (as `hinf train`) into out/; progress(p: TrainProgress) after every time step");
    m.def(
        "resume",
        [](const std::string& checkpoint, double until, const py::object& progress, bool quiet, int threads) {
            hinf::TrainSettings s = train_settings("", until, progress, quiet, false, threads);
            hinf::TrainReport r;
            {
                py::gil_scoped_release nogil;
                r = hinf::resume(checkpoint, s);
            }
            return report_dict(r);
        },
        py::arg("checkpoint"), py::arg("until") = -1.0, py::arg("progress") = py::none(), py::arg("quiet") = true,
        py::arg("threads") = 0, "Continues a run from its checkpoint (as `hinf resume`)");
}
