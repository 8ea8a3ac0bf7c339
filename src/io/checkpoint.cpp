// HDF5 checkpoints (see checkpoint.hpp and docs/formats.md).
#include "io/checkpoint.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

#include <toml++/toml.h>

#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "io/isolate.hpp"

namespace hinf {

namespace {

template <typename T>
void write_array(hid_t loc, const std::string& name, const std::vector<T>& v, const std::vector<hsize_t>& dims,
                 const std::string& meaning) {
    if constexpr (std::is_same_v<T, float>)
        h5::write_floats(loc, name, v.data(), dims, "", meaning, true);
    else
        h5::write_doubles(loc, name, v.data(), dims, "", meaning, true);
}

template <typename T>
std::vector<T> read_array(hid_t loc, const std::string& name, std::vector<hsize_t>* dims) {
    if constexpr (std::is_same_v<T, float>)
        return h5::read_floats(loc, name, dims);
    else
        return h5::read_doubles(loc, name, dims);
}

// Test hook, documented in docs/reliability.md: HINF_TEST_CHECKPOINT_PAUSE_MS=k sleeps k ms in the
// middle of writing checkpoint.h5.tmp so that the kill -9 tests can hit a half-written checkpoint.
void test_pause_mid_write() {
    const char* ms = std::getenv("HINF_TEST_CHECKPOINT_PAUSE_MS");
    if (ms && *ms) std::this_thread::sleep_for(std::chrono::milliseconds(std::atoi(ms)));
}

// Reads a whole checkpoint of either precision (throws hinf::Error when damaged).
void read_any(const std::string& path) {
    if (ckpt_precision(path) == "float") ckpt_read<float>(path);
    else ckpt_read<double>(path);
}

// What identifies a file's contents: its device, inode and size, and a digest of its bytes (read through, not
// parsed: HDF5 never sees them).
struct FileId {
    dev_t dev = 0;
    ino_t ino = 0;
    off_t size = 0;
    std::uint64_t digest = 0;
    bool operator==(const FileId& o) const {
        return dev == o.dev && ino == o.ino && size == o.size && digest == o.digest;
    }
};

// Files above this size are always read in a child: hashing them would cost what the child costs.
constexpr off_t kHashedFileMax = off_t(256) << 20;

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t bytes);

// The identity of a regular file of at most kHashedFileMax bytes; false for anything else (a FIFO would block).
bool file_id(const std::string& path, FileId* id) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size > kHashedFileMax) return false;
    id->dev = st.st_dev;
    id->ino = st.st_ino;
    id->size = st.st_size;
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr) return false;
    std::uint64_t h = 14695981039346656037ull;
    std::vector<char> buf(std::size_t(1) << 16);
    off_t total = 0;
    for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), f)) > 0;) {
        h = fnv1a(h, buf.data(), n);
        total += off_t(n);
    }
    const bool ok = !std::ferror(f) && total == st.st_size;
    std::fclose(f);
    id->digest = h;
    return ok;
}

// The checkpoint files this process has seen read cleanly (committed by ckpt_write after reading them back as
// written, or read in a child by read_in_child), by their identity then. A file that still has one of these
// identities holds bytes that were read cleanly, so read_in_child does not read it again in a forked child: a
// training that validates each new checkpoint and keeps the last two forked the whole process two or three times a
// checkpoint, and the acceptance check once more for each of its parts (docs/reliability.md section 5). A file
// changed in any byte since, and every file of a new process, are read in a child as before.
std::mutex g_clean_mutex;
std::vector<FileId> g_clean;

void remember_clean(const FileId& id) {
    std::lock_guard<std::mutex> lock(g_clean_mutex);
    g_clean.push_back(id);
    if (g_clean.size() > 64) g_clean.erase(g_clean.begin());  // the files in use are the last few
}

bool seen_clean(const FileId& id) {
    std::lock_guard<std::mutex> lock(g_clean_mutex);
    for (const FileId& c : g_clean)
        if (c == id) return true;
    return false;
}

// Reads path in a child process (io/isolate.hpp): "" when it read cleanly, else the problem. A file this process
// has seen read cleanly and that has not changed since is not read again. (The digest is taken before the child
// reads: a file changed meanwhile is remembered by bytes it no longer has, and read in a child next time.)
std::string read_in_child(const std::string& path) {
    FileId id;
    const bool hashed = file_id(path, &id);
    if (hashed && seen_clean(id)) return "";
    std::string problem = run_isolated([&path] { read_any(path); });
    if (hashed && problem.empty()) remember_clean(id);
    return problem;
}

// FNV-1a over bytes, continued from h.
std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t bytes) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

// The digest that binds a checkpoint's contents together: weights, Adam moments and counters, the state, the
// step and the config. A value edited after writing (a step relabelled, a weight replaced with its checksum
// recomputed) no longer matches; fletcher32 alone only catches damage, not edits.
template <typename T>
std::string content_digest(const Checkpoint<T>& ck) {
    std::uint64_t h = 14695981039346656037ull;
    auto vec = [&h](const auto& v) { h = fnv1a(h, v.data(), v.size() * sizeof(v[0])); };
    vec(ck.net.theta);
    vec(ck.adam_m);
    vec(ck.adam_v);
    vec(ck.state.x);
    vec(ck.state.xhat);
    h = fnv1a(h, &ck.state.step, sizeof ck.state.step);
    h = fnv1a(h, &ck.state.adam_step, sizeof ck.state.adam_step);
    h = fnv1a(h, &ck.state.learning_rate_scale, sizeof ck.state.learning_rate_scale);
    h = fnv1a(h, ck.config_text.data(), ck.config_text.size());
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
}

// The first non-finite value of v, as "NAME[i] = value", or "".
template <typename V>
std::string first_non_finite(const V& v, const std::string& name) {
    for (std::size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(double(v[i]))) return name + "[" + std::to_string(i) + "] = " + std::to_string(double(v[i]));
    return "";
}

}  // namespace

template <typename T>
std::string ckpt_non_finite(const Checkpoint<T>& ck) {
    for (const std::string& what :
         {first_non_finite(ck.net.theta, "network weight"), first_non_finite(ck.adam_m, "Adam moment m"),
          first_non_finite(ck.adam_v, "Adam moment v"), first_non_finite(ck.state.x, "state x"),
          first_non_finite(ck.state.xhat, "estimate x^")})
        if (!what.empty()) return what;
    return "";
}

std::string ckpt_prev_name(const std::string& path) {
    std::string base = path;
    if (base.size() > 3 && base.compare(base.size() - 3, 3, ".h5") == 0) base.resize(base.size() - 3);
    return base + ".prev.h5";
}

template <typename T>
void ckpt_write(const std::string& path, const Checkpoint<T>& ck, const RunConfig& cfg) {
    const std::string tmp = path + ".tmp";
    // a checkpoint is kept as good: it must be usable (the trainer stops as diverged before this)
    const std::string bad = ckpt_non_finite(ck);
    HINF_CHECK(bad.empty(), "refusing to write checkpoint '" + path + "': " + bad + " is not finite; '" + path +
                                "' is kept");
    {
        h5::Handle f = h5::create_file(tmp);
        hid_t root = f.get();
        h5::set_attr(root, "format", "hinf-checkpoint");
        h5::set_attr(root, "format_version", kCheckpointFormatVersion);
        h5::set_attr(root, "step", ck.state.step);
        h5::set_attr(root, "time", double(ck.state.step) * cfg.dt);
        h5::set_attr(root, "config_hash", config_hash(ck.config_text));
        h5::set_attr(root, "precision", std::is_same_v<T, float> ? "float" : "double");
        h5::set_attr(root, "filter_type", cfg.type);
        h5::set_attr(root, "variant", cfg.variant);
        h5::set_attr(root, "content_digest", content_digest(ck));
        h5::write_string(root, "config", ck.config_text, "the effective TOML config of the run");

        const kern::StepConfig& sc = ck.net.step;
        h5::Handle net = h5::create_group(root, "network");
        std::vector<double> sizes(sc.shape.sizes.begin(), sc.shape.sizes.end());
        h5::set_attr(net.get(), "sizes", sizes);
        h5::set_attr(net.get(), "slopes", std::vector<double>{sc.shape.slope_positive, sc.shape.slope_negative});
        h5::set_attr(net.get(), "head", sc.gain.enabled                         ? "gain"
                                        : sc.head.kind == kern::HEAD_GRADIENT ? "gradient"
                                                                              : "quadratic");
        h5::set_attr(net.get(), "input_scale", sc.input_scale);
        h5::set_attr(net.get(), "error_floor", cfg.error_floor);  // (and: written after the floor's 2026-11-27 rule)
        h5::set_attr(net.get(), "output_scale", sc.head.scale);
        h5::set_attr(net.get(), "eps", sc.head.eps);
        h5::set_attr(net.get(), "meaning",
                     "network input = x~ / input_scale; head gradient: dV/dx~ = output_scale * o; head quadratic: "
                     "dV/dx~ = output_scale * (M M^T + eps I) x~, M = I + tril(o)");
        for (int l = 1; l <= sc.shape.layers(); ++l) {
            const int din = sc.shape.sizes[l - 1], dout = sc.shape.sizes[l];
            h5::Handle g = h5::create_group(net.get(), "layer_" + std::to_string(l));
            const T* W = ck.net.theta.data() + sc.shape.weight_offset(l);
            std::vector<T> w(W, W + std::int64_t(din) * dout), b(W + std::int64_t(din) * dout, W + std::int64_t(din) * dout + dout);
            write_array(g.get(), "W", w, {hsize_t(dout), hsize_t(din)}, "weights [out x in]");
            write_array(g.get(), "b", b, {hsize_t(dout)}, "biases");
        }
        if (sc.gain.enabled) {  // variant gain: the storage's parameters follow the MLP's in theta
            const std::int64_t P = sc.shape.param_count(), ns = sc.gain.storage_params(cfg.n);
            std::vector<T> sp(ck.net.theta.begin() + P, ck.net.theta.begin() + P + ns);
            write_array(net.get(), "storage", sp, {hsize_t(ns)},
                        sc.gain.knots > 0
                            ? "storage V = x~'S(t)x~ on storage_knots + 1 knots of n(n+1)/2: S = c D^-1 (M M' + eps I) "
                              "D^-1, M = diag(exp) + strict tril, linear in t between knots (docs/method.md §16.7)"
                            : "storage V = x~'S x~: S = c D^-1 (M M' + eps I) D^-1, M = I + tril(storage) (docs/method.md §16)");
            h5::set_attr(net.get(), "storage_knots", std::int64_t(sc.gain.knots));
            h5::set_attr(net.get(), "gain_head", std::string(sc.gain.kalman ? "kalman" : "direct"));
            h5::set_attr(net.get(), "gain_structure", cfg.gain_structure);  // since 2026-11-28 (method.md 16.17)
            h5::set_attr(net.get(), "angle_inputs", cfg.angle_inputs);      // since 2026-12-07 (method.md 16.19)
            h5::set_attr(net.get(), "input_shift", sc.gain.shift);
            h5::set_attr(net.get(), "input_spread", sc.gain.spread);
            h5::set_attr(net.get(), "error_scale", sc.gain.dx);
            h5::set_attr(net.get(), "innovation_scale", sc.gain.dy);
            h5::set_attr(net.get(), "gain_rate", sc.gain.rate);
            h5::set_attr(net.get(), "storage_scale", sc.gain.storage_scale);
            h5::set_attr(net.get(), "errors_per_estimate", std::int64_t(sc.gain.group));
            if (!sc.gain.zlo.empty()) {  // where the filter holds the network's input (method.md 16.10)
                h5::set_attr(net.get(), "input_low", sc.gain.zlo);
                h5::set_attr(net.get(), "input_high", sc.gain.zhi);
            }
            if (sc.gain.knots > 0) {
                h5::set_attr(net.get(), "storage_state_scale",
                             std::vector<double>(sc.gain.storage_dx(), sc.gain.storage_dx() + cfg.n));
                h5::set_attr(net.get(), "storage_init", cfg.storage_init);
                // the knots' spacing (network.knot_ratio; a file without it has uniform knots, the default so far)
                h5::set_attr(net.get(), "knot_ratio", cfg.knot_ratio);
            }
        }
        h5::flush(root);
        test_pause_mid_write();
        h5::Handle adam = h5::create_group(root, "adam");
        h5::set_attr(adam.get(), "step", ck.state.adam_step);
        h5::set_attr(adam.get(), "learning_rate_scale", ck.state.learning_rate_scale);
        // how the moments go from one time step to the next (training.reset_adam_each_step, whose default for the
        // gain variant changed on 2026-11-26): a file without it was written with them reset
        h5::set_attr(adam.get(), "reset_each_step", std::int64_t(cfg.reset_adam ? 1 : 0));
        write_array(adam.get(), "m", ck.adam_m, {hsize_t(ck.adam_m.size())}, "first-moment average m_k (eq. 15)");
        write_array(adam.get(), "v", ck.adam_v, {hsize_t(ck.adam_v.size())}, "second-moment average v_k (eq. 15)");

        h5::Handle st = h5::create_group(root, "state");
        const hsize_t n = ck.state.x.size();
        std::vector<double> xt(n);
        for (hsize_t i = 0; i < n; ++i) xt[i] = ck.state.x[i] - ck.state.xhat[i];
        h5::write_doubles(st.get(), "x", ck.state.x.data(), {n}, "state units", "true state x(t)", true);
        h5::write_doubles(st.get(), "xhat", ck.state.xhat.data(), {n}, "state units", "estimate x^(t)", true);
        h5::write_doubles(st.get(), "xtilde", xt.data(), {n}, "state units", "estimation error x - x^", true);
        h5::set_attr(st.get(), "step", ck.state.step);

        h5::Handle rng = h5::create_group(root, "rng");
        h5::set_attr(rng.get(), "generator", "Philox4x32-10");
        h5::set_attr(rng.get(), "seed", static_cast<std::int64_t>(cfg.seed));
        h5::set_attr(rng.get(), "counter", ck.state.step);
        h5::flush(root);
    }
    sync_path(tmp);
    // the old checkpoint is only demoted once the new one reads back with the same arrays
    Checkpoint<T> back = ckpt_read<T>(tmp);
    HINF_CHECK(back.net.theta == ck.net.theta && back.adam_m == ck.adam_m && back.adam_v == ck.adam_v &&
                   back.state.step == ck.state.step,
               "checkpoint '" + tmp + "' does not read back as written (disk trouble?); '" + path + "' is kept");
    // keep the last two: the current file becomes prev (a hard link, so that path never disappears),
    // then tmp replaces path in one atomic rename
    std::error_code ec;
    const std::string prev = ckpt_prev_name(path);
    bool current_good = std::filesystem::exists(path);
    // a damaged checkpoint.h5 (a resume from prev) must not push out the good prev
    if (current_good) current_good = read_in_child(path).empty();
    if (current_good) {
        std::filesystem::remove(prev, ec);
        std::filesystem::create_hard_link(path, prev, ec);
        if (ec) std::filesystem::copy_file(path, prev, std::filesystem::copy_options::overwrite_existing, ec);
        HINF_CHECK(!ec, "cannot keep '" + path + "' as '" + prev + "': " + ec.message());
    }
    commit_rename(tmp, path);
    FileId id;
    if (file_id(path, &id)) remember_clean(id);
}

namespace {
// The checks and readers below take the file open once: each H5Fopen allocates and clears libhdf5's metadata cache
// (half a megabyte, fresh pages under the sanitizers' allocator), and a network's load opened its file seven times.
std::string precision_of(hid_t f, const std::string& path) {
    HINF_CHECK(h5::has_attr(f, "format") && h5::get_attr_string(f, "format") == "hinf-checkpoint",
               "'" + path + "' is not a hinf checkpoint (pass DIR/checkpoint.h5 written by `hinf train`)");
    std::int64_t version = h5::get_attr_int(f, "format_version");
    HINF_CHECK(version == kCheckpointFormatVersion,
               "checkpoint '" + path + "' has format version " + std::to_string(version) + ", this hinf reads " +
                   std::to_string(kCheckpointFormatVersion) + " (use the hinf that wrote it)");
    return h5::get_attr_string(f, "precision");
}
}  // namespace

std::string ckpt_precision(const std::string& path) {
    h5::Handle f = h5::open_file(path, false);
    return precision_of(f.get(), path);
}

namespace {
// The settings a file's config leaves to a default that has changed since the file was written, as the values it was
// trained with ("section.key=value"): no variant and no storage; no storage_knots, errors_per_estimate, input box or
// reset_each_step attribute, ... Empty for a file of this hinf. The one list of these rules: the effective config
// applies it, and resume records it (trainer.cpp).
std::vector<std::string> ckpt_as_trained_sets(hid_t file, const ConfigDoc& doc) {
    std::vector<std::string> sets;
    // a key the file's config leaves to the default: the value it trained with
    auto as_trained = [&](const char* section, const char* key, const std::string& value) {
        if (!ConfigSection(doc, section).has(key)) sets.push_back(std::string(section) + "." + key + "=" + value);
    };
    // a value the file fixes whatever its config says (a config naming that value already needs no record)
    auto pinned = [&](const char* section, const char* key, const std::string& value) {
        const std::string assignment = std::string(section) + "." + key + "=" + value;
        ConfigDoc with = doc;
        with.set(assignment);
        if (!ConfigSection(doc, section).has(key) || with.text() != doc.text()) sets.push_back(assignment);
    };
    h5::Handle net = h5::open_group(file, "network");
    if (!h5::exists(file, "network/storage")) {
        // no storage: not a gain network; a config naming no variant trained `dissipative`, whatever the default now
        if (!ConfigSection(doc, "filter").has("variant")) {
            ConfigDoc trained = doc;  // loaded as it trained (as the default now, it may not load)
            trained.set("filter.variant=\"dissipative\"");
            const RunConfig c = load_run_config(trained);
            if (default_variant(c.type, c.n, c.m, c.nv) != "dissipative") sets.push_back("filter.variant=\"dissipative\"");
        }
    } else {
        h5::Handle adam = h5::open_group(file, "adam");
        if (!h5::has_attr(net.get(), "storage_knots")) {  // one constant S, whatever the config says
            pinned("network", "storage_knots", "0");
        } else if (h5::get_attr_int(net.get(), "storage_knots") > 0) {
            // an S(t) network written before network.storage_scaling existed has the one-scalar scale; one written
            // before network.storage_init existed started flat and trained with the old default margin 0.02
            if (!h5::has_attr(net.get(), "storage_state_scale")) pinned("network", "storage_scaling", "\"mean\"");
            if (!h5::has_attr(net.get(), "storage_init")) {
                as_trained("network", "storage_init", "\"flat\"");
                as_trained("objective", "margin", "0.02");
            }
        }
        // written before errors were grouped per estimate; when gain training reset Adam every time step; before the
        // filter held its input (or with no box drawn)
        if (!h5::has_attr(net.get(), "errors_per_estimate")) as_trained("sampling", "errors_per_estimate", "1");
        if (!h5::has_attr(adam.get(), "reset_each_step")) as_trained("training", "reset_adam_each_step", "true");
        if (!h5::has_attr(net.get(), "input_low")) as_trained("network", "input_box", "0");
        // written before the gain had structural zeros (docs/method.md section 16.17): every entry learned
        if (!h5::has_attr(net.get(), "gain_structure")) as_trained("network", "gain_structure", "\"full\"");
        // written before an angle state was seen as (cos, sin) (docs/method.md section 16.19): standardised
        if (!h5::has_attr(net.get(), "angle_inputs") && doc.root()["system"]["angle_states"].as_array() != nullptr)
            as_trained("network", "angle_inputs", "\"raw\"");
    }
    const std::string kind = ConfigSection(doc, "system").get_string("kind", "missile");
    // written before a system of one's own that names no rho got 1.25 times its linearised game's level
    // (docs/method.md section 16.12): it trained at the missile's 0.03; and before one that names no Q got Q = I: it
    // trained with the missile's 1e-5 I. Every checkpoint since has both in its config
    if (kind == "expr") {
        as_trained("filter", "rho", "0.03");
        const toml::array* states = doc.root()["system"]["states"].as_array();
        if (states != nullptr && !states->empty()) {
            std::string q = "[";
            for (std::size_t i = 0; i < states->size(); ++i) q += i ? ", 1e-05" : "1e-05";
            as_trained("filter", "Q", q + "]");
        }
    }
    // written before a state started without error got a floor from its motion (error_floor_default): the samples,
    // and a gain network's error scale, were the old floor's. The missiles' floor never changed (20 m), so their
    // config is not loaded again here (loading one of the own systems walks its nominal trajectory)
    if (kind != "missile" && kind != "maneuvering_missile" && !h5::has_attr(net.get(), "error_floor") &&
        !ConfigSection(doc, "sampling").has("error_floor")) {
        ConfigDoc trained = doc;
        for (const std::string& a : sets) trained.set(a);
        const RunConfig c = load_run_config(trained);
        const std::vector<double> was = error_floor_default(c, true);
        if (was != c.error_floor) {
            std::string v = "[";
            char b[32];
            for (std::size_t i = 0; i < was.size(); ++i) {
                std::snprintf(b, sizeof b, "%.17g", was[i]);
                v += (i ? ", " : "") + std::string(b);
            }
            sets.push_back("sampling.error_floor=" + v + "]");
        }
    }
    return sets;
}

// The checkpoint's config as it was trained: the stored text with the as-trained settings applied.
std::string ckpt_effective_config_text(hid_t file, const std::string& path, std::vector<std::string>* sets_out) {
    std::string text = h5::read_string(file, "config");
    HINF_CHECK(config_hash(text) == h5::get_attr_string(file, "config_hash"),
               "checkpoint '" + path + "': stored config does not match its hash (the file is damaged)");
    ConfigDoc doc = ConfigDoc::from_text(text, path + ":/config");
    std::vector<std::string> sets = ckpt_as_trained_sets(file, doc);
    for (const std::string& s : sets) doc.set(s);
    if (sets_out) *sets_out = sets;
    return sets.empty() ? text : doc.text();
}

RunConfig config_of(hid_t f, const std::string& path) {
    precision_of(f, path);
    RunConfig c = load_run_config(ConfigDoc::from_text(ckpt_effective_config_text(f, path, nullptr), path + ":/config"));
    c.chosen = chosen_keys(h5::read_string(f, "config"));  // (the effective text of a legacy file keeps no comments)
    return c;
}

// ckpt_read on an open file; its config, loaded once, goes to *cfg_out when given
template <typename T>
Checkpoint<T> read_of(const h5::Handle& f, const std::string& path, RunConfig* cfg_out);
}  // namespace

std::vector<std::string> ckpt_as_trained(const std::string& path) {
    h5::Handle f = h5::open_file(path, false);
    precision_of(f.get(), path);
    std::vector<std::string> sets;
    ckpt_effective_config_text(f.get(), path, &sets);
    return sets;
}

RunConfig ckpt_config(const std::string& path) {
    h5::Handle f = h5::open_file(path, false);
    return config_of(f.get(), path);
}

template <typename T>
Checkpoint<T> ckpt_read(const std::string& path) {
    h5::Handle f = h5::open_file(path, false);
    return read_of<T>(f, path, nullptr);
}

namespace {
template <typename T>
Checkpoint<T> read_of(const h5::Handle& f, const std::string& path, RunConfig* cfg_out) {
    std::string precision = precision_of(f.get(), path);
    const char* want = std::is_same_v<T, float> ? "float" : "double";
    HINF_CHECK(precision == want, "checkpoint '" + path + "' holds a " + precision + " network, expected " + want);
    RunConfig cfg = config_of(f.get(), path);
    Checkpoint<T> ck;
    ck.config_text = h5::read_string(f.get(), "config");  // as written (the digest covers it; ckpt_config: effective)
    ck.net = network_shell<T>(cfg);  // shapes and scales from the config; no random draws, no OpenMP
    const kern::StepConfig& sc = ck.net.step;
    h5::Handle net = h5::open_group(f.get(), "network");
    std::vector<double> sizes = h5::get_attr_doubles(net.get(), "sizes");
    HINF_CHECK(sizes == std::vector<double>(sc.shape.sizes.begin(), sc.shape.sizes.end()),
               "checkpoint '" + path + "': network sizes do not match its config (damaged file)");
    HINF_CHECK(h5::get_attr_double(net.get(), "input_scale") == sc.input_scale &&
                   h5::get_attr_double(net.get(), "output_scale") == sc.head.scale,
               "checkpoint '" + path + "': scales do not match its config (damaged file)");
    for (int l = 1; l <= sc.shape.layers(); ++l) {
        const int din = sc.shape.sizes[l - 1], dout = sc.shape.sizes[l];
        h5::Handle g = h5::open_group(net.get(), "layer_" + std::to_string(l));
        std::vector<hsize_t> dw, db;
        std::vector<T> w = read_array<T>(g.get(), "W", &dw), b = read_array<T>(g.get(), "b", &db);
        HINF_CHECK((dw == std::vector<hsize_t>{hsize_t(dout), hsize_t(din)} && db == std::vector<hsize_t>{hsize_t(dout)}),
                   "checkpoint '" + path + "': layer_" + std::to_string(l) + " has the wrong shape");
        T* W = ck.net.theta.data() + sc.shape.weight_offset(l);
        std::copy(w.begin(), w.end(), W);
        std::copy(b.begin(), b.end(), W + std::int64_t(din) * dout);
    }
    if (sc.gain.enabled) {
        const std::int64_t P = sc.shape.param_count(), ns = sc.gain.storage_params(cfg.n);
        std::vector<T> sp = read_array<T>(net.get(), "storage", nullptr);
        if (std::int64_t(sp.size()) != ns) {
            // the storage's size follows network.storage_knots; files written before the key existed have one S
            const std::int64_t np = std::int64_t(cfg.n) * (cfg.n + 1) / 2, size = std::int64_t(sp.size());
            std::int64_t knots = size % np == 0 ? (size == np ? 0 : size / np - 1) : -1;
            if (h5::has_attr(net.get(), "storage_knots")) knots = h5::get_attr_int(net.get(), "storage_knots");
            HINF_FAIL("checkpoint '" + path + "': network/storage has " + std::to_string(sp.size()) +
                      " parameters, the config's network.storage_knots = " + std::to_string(sc.gain.knots) + " needs " +
                      std::to_string(ns) +
                      (knots >= 0 ? " (the network was trained with storage_knots = " + std::to_string(knots) +
                                        ": add --set network.storage_knots=" + std::to_string(knots) + ")"
                                  : " (damaged file, or another config)"));
        }
        HINF_CHECK(h5::get_attr_doubles(net.get(), "input_shift") == sc.gain.shift &&
                       h5::get_attr_doubles(net.get(), "input_spread") == sc.gain.spread,
                   "checkpoint '" + path + "': input standardisation does not match its config (damaged file, or "
                   "the system's model changed since training)");
        std::copy(sp.begin(), sp.end(), ck.net.theta.begin() + P);
        if (h5::has_attr(net.get(), "input_low")) {  // the box is drawn at creation and travels with the network
            kern::GainSpec& g = ck.net.step.gain;
            g.zlo = h5::get_attr_doubles(net.get(), "input_low");
            g.zhi = h5::get_attr_doubles(net.get(), "input_high");
            bool ok = g.zlo.size() == std::size_t(cfg.n) && g.zhi.size() == std::size_t(cfg.n);
            for (std::size_t j = 0; ok && j < g.zlo.size(); ++j) ok = g.zlo[j] <= g.zhi[j];
            HINF_CHECK(ok, "checkpoint '" + path + "': network/input_low and input_high must be " +
                               std::to_string(cfg.n) + " ordered bounds (damaged file)");
        }
    }
    h5::Handle adam = h5::open_group(f.get(), "adam");
    ck.state.adam_step = h5::get_attr_int(adam.get(), "step");
    if (h5::has_attr(adam.get(), "learning_rate_scale"))
        ck.state.learning_rate_scale = h5::get_attr_double(adam.get(), "learning_rate_scale");
    HINF_CHECK(ck.state.learning_rate_scale > 0 && ck.state.learning_rate_scale <= 1,
               "checkpoint '" + path + "': adam/learning_rate_scale must be in (0, 1] (damaged file)");
    ck.adam_m = read_array<T>(adam.get(), "m", nullptr);
    ck.adam_v = read_array<T>(adam.get(), "v", nullptr);
    HINF_CHECK(ck.adam_m.size() == ck.net.theta.size() && ck.adam_v.size() == ck.net.theta.size(),
               "checkpoint '" + path + "': Adam moments have the wrong size");
    h5::Handle st = h5::open_group(f.get(), "state");
    ck.state.step = h5::get_attr_int(f.get(), "step");
    ck.state.x = h5::read_doubles(st.get(), "x");
    ck.state.xhat = h5::read_doubles(st.get(), "xhat");
    HINF_CHECK(int(ck.state.x.size()) == cfg.n && int(ck.state.xhat.size()) == cfg.n,
               "checkpoint '" + path + "': state has the wrong dimension");
    HINF_CHECK(ck.state.step >= 0, "checkpoint '" + path + "': negative step");
    // the step is stored three times (root, state, RNG counter): an edited copy disagrees with the others
    HINF_CHECK(h5::get_attr_int(st.get(), "step") == ck.state.step &&
                   h5::get_attr_int(h5::open_group(f.get(), "rng").get(), "counter") == ck.state.step,
               "checkpoint '" + path + "': its step attributes disagree (root " + std::to_string(ck.state.step) +
                   ", state " + std::to_string(h5::get_attr_int(st.get(), "step")) +
                   "): the file was edited or damaged (resume from checkpoint.prev.h5 or train again)");
    const std::string bad = ckpt_non_finite(ck);
    HINF_CHECK(bad.empty(), "checkpoint '" + path + "': " + bad + " is not finite, so the network is unusable "
                                                              "(resume from checkpoint.prev.h5 or train again)");
    // files written before the digest existed have none; every file this hinf writes has one
    if (h5::has_attr(f.get(), "content_digest"))
        HINF_CHECK(h5::get_attr_string(f.get(), "content_digest") == content_digest(ck),
                   "checkpoint '" + path + "': its contents do not match its digest (a weight, moment, state or "
                   "step was changed after writing; resume from checkpoint.prev.h5 or train again)");
    if (cfg_out) *cfg_out = std::move(cfg);
    return ck;
}
}  // namespace

void ckpt_verify(const std::string& path) {
    const std::string what = read_in_child(path);
    if (what.empty()) return;
    std::string msg = what.find(path) != std::string::npos ? what : "checkpoint '" + path + "': " + what;
    const std::string prev = ckpt_prev_name(path);
    if (prev != path && std::filesystem::exists(prev) && read_in_child(prev).empty())
        msg += "; the previous checkpoint is good: hinf resume " + prev;
    throw Error(msg);
}

std::unique_ptr<FrozenNetwork> ckpt_frozen_network(const std::string& path, RunConfig* cfg_out) {
    ckpt_verify(path);  // in a child process first: a file that crashes libhdf5 gives one line
    h5::Handle f = h5::open_file(path, false);
    if (precision_of(f.get(), path) == "float") return network_freeze(read_of<float>(f, path, cfg_out).net);
    return network_freeze(read_of<double>(f, path, cfg_out).net);
}

template void ckpt_write<float>(const std::string&, const Checkpoint<float>&, const RunConfig&);
template void ckpt_write<double>(const std::string&, const Checkpoint<double>&, const RunConfig&);
template Checkpoint<float> ckpt_read<float>(const std::string&);
template std::string ckpt_non_finite<float>(const Checkpoint<float>&);
template std::string ckpt_non_finite<double>(const Checkpoint<double>&);
template Checkpoint<double> ckpt_read<double>(const std::string&);

}  // namespace hinf
