// The sweep driver (see sweep.hpp): groups of processes, one directory per value, a summary line per value
// that marks it finished, the table gathered in value order.
#include "train/sweep.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "io/atomic.hpp"
#include "io/checkpoint.hpp"
#include "io/progress.hpp"
#include "io/run_lock.hpp"
#include "io/run_swap.hpp"
#include "par/par.hpp"

namespace hinf {

namespace {

const char* kSummaryHeader =
    "value,how,status,first_step,last_step,wall_seconds,final_loss,median_rel_residual,fraction_steps_rel_ok,"
    "fraction_steps_violation_ok,mean_cosine,best_step,select_score,acceptance,acceptance_rmse_position,"
    "acceptance_worst_ratio,acceptance_rmse_position_settled,acceptance_rmse_position_settled_ekf,knot_runaway_step,"
    "acceptance_rms_q_settled,acceptance_rms_q_settled_ekf,rho,search_ratio,search_ratio_ekf,search_ratio_ukf,"
    "search_diverged";
// older summary lines: the trainer's 11 fields alone (before the selection and acceptance columns), 16 (before the
// comparison with the EKF and the knot run-away), 19 (before the all-state comparison) and 21 (before --worst)
constexpr std::size_t kFieldsBefore = 11, kFieldsVerdict = 16, kFieldsEkf = 19, kFieldsQ = 21, kFields = 26;

// one CSV line per value (values with a comma are refused up front)
std::string row_line(const SweepRow& r) {
    std::ostringstream o;
    o.precision(17);
    const TrainSummary& s = r.summary;
    o << r.value << ',' << r.how << ',' << s.status << ',' << s.first_step << ',' << s.last_step << ','
      << s.wall_seconds << ',' << s.final_loss << ',' << s.median_rel_residual << ',' << s.fraction_steps_rel_ok
      << ',' << s.fraction_steps_violation_ok << ',' << s.mean_cosine;
    const SweepVerdict& v = r.verdict;
    o << ',' << v.best_step << ',' << v.select_score << ',' << v.acceptance << ',' << v.rmse_position << ','
      << v.worst_ratio << ',' << v.rmse_settled << ',' << v.rmse_settled_ekf << ',' << s.runaway_step << ','
      << v.rms_q_settled << ',' << v.rms_q_settled_ekf << ',' << v.rho << ',' << v.search_ratio << ','
      << v.search_ratio_ekf << ',' << v.search_ratio_ukf << ',' << v.search_diverged;
    return o.str();
}

SweepRow parse_line(const std::string& line, const std::string& where) {
    std::vector<std::string> f;
    std::stringstream in(line);
    for (std::string cell; std::getline(in, cell, ',');) f.push_back(cell);
    HINF_CHECK(f.size() == kFields || f.size() == kFieldsQ || f.size() == kFieldsEkf || f.size() == kFieldsVerdict ||
                   f.size() == kFieldsBefore,
               where + ": not a sweep summary line (delete the file to train that value again)");
    SweepRow r;
    r.value = f[0];
    r.how = f[1];
    TrainSummary& s = r.summary;
    s.status = std::stoi(f[2]);
    s.first_step = std::stoll(f[3]);
    s.last_step = std::stoll(f[4]);
    s.wall_seconds = std::stod(f[5]);
    s.final_loss = std::stod(f[6]);
    s.median_rel_residual = std::stod(f[7]);
    s.fraction_steps_rel_ok = std::stod(f[8]);
    s.fraction_steps_violation_ok = std::stod(f[9]);
    s.mean_cosine = std::stod(f[10]);
    if (f.size() >= kFieldsVerdict) {  // stod reads "nan" back
        SweepVerdict& v = r.verdict;
        v.best_step = std::stoll(f[11]);
        v.select_score = std::stod(f[12]);
        v.acceptance = f[13];
        v.rmse_position = std::stod(f[14]);
        v.worst_ratio = std::stod(f[15]);
    }
    if (f.size() >= kFieldsEkf) {
        r.verdict.rmse_settled = std::stod(f[16]);
        r.verdict.rmse_settled_ekf = std::stod(f[17]);
        s.runaway_step = std::stoll(f[18]);
    }
    if (f.size() >= kFieldsQ) {
        r.verdict.rms_q_settled = std::stod(f[19]);
        r.verdict.rms_q_settled_ekf = std::stod(f[20]);
    }
    if (f.size() == kFields) {
        r.verdict.rho = std::stod(f[21]);
        r.verdict.search_ratio = std::stod(f[22]);
        r.verdict.search_ratio_ekf = std::stod(f[23]);
        r.verdict.search_ratio_ukf = std::stod(f[24]);
        r.verdict.search_diverged = std::stoi(f[25]);
    }
    return r;
}

SweepRow train_value(const std::string& config_path, const SweepOptions& opt, const std::string& value) {
    SweepRow row;
    row.value = value;
    row.dir = opt.out_dir + "/" + sweep_dir_name(opt.key, value);
    const std::string done = row.dir + "/summary.csv", ckpt = row.dir + "/checkpoint.h5";
    if (std::filesystem::exists(done)) {  // finished by an earlier job: its line, not a new training
        std::ifstream in(done);
        std::string header, line;
        std::getline(in, header);
        std::getline(in, line);
        SweepRow r = parse_line(line, done);
        r.dir = row.dir;
        r.how = "done before";
        return r;
    }
    // a kill during the value's exchange of two runs (another storage or game kept, eval/acceptance.hpp) may have
    // left its checkpoint in DIR/alternative.swap: the lock of DIR finishes the exchange first, so that the value
    // resumes from its checkpoint instead of training afresh (the group's other ranks wait for its root)
    if (par_root() && std::filesystem::exists(row.dir + "/" + kSwapFolder)) {
        const RunDirLock settle(row.dir, "hinf sweep");
    }
    par_barrier();
    TrainOptions to;
    to.out_dir = row.dir;
    to.until = opt.until;
    // several trainings at once (process groups): the table at the end says how each went; one after another: each
    // says its progress as `hinf train` does
    to.quiet = opt.quiet || par_world_size() > par_size();
    if (std::filesystem::exists(ckpt)) {
        row.how = "resumed";
        const SweepTrain train = [&](const TrainOptions& o) { return train_resume(ckpt, o); };
        RunConfig cfg;
        bool readable = false;
        try {  // read in a child first: a damaged file may crash the HDF5 library; train_resume reports it
            ckpt_verify(ckpt);
            cfg = ckpt_config(ckpt);
            readable = true;
        } catch (const std::exception&) {
        }
        if (opt.around && readable) row.verdict = opt.around(cfg, row.dir, true, to, row.summary);
        else row.summary = train(to);
    } else {
        ConfigDoc doc = ConfigDoc::from_file(config_path);
        for (const auto& s : opt.sets) doc.set(s);
        doc.set(opt.key + "=" + value);
        row.how = "trained";
        const RunConfig cfg = load_run_config(std::move(doc));
        const SweepTrain train = [&](const TrainOptions& o) { return train_start(cfg, o); };
        if (opt.around) row.verdict = opt.around(cfg, row.dir, false, to, row.summary);
        else row.summary = train(to);
    }
    write_text_atomic(done, [&](std::ostream& o) { o << kSummaryHeader << '\n' << row_line(row) << '\n'; });
    return row;
}

}  // namespace

std::string sweep_dir_name(const std::string& key, const std::string& value) {
    std::string s = key + "=" + value;
    for (char& c : s)
        if (c == '/' || c == '\\' || c == ' ' || c == '"' || c == '\'' || c == '[' || c == ']') c = '_';
    return s;
}

std::vector<SweepRow> sweep_run(const std::string& config_path, const SweepOptions& opt) {
    HINF_CHECK(!opt.key.empty() && !opt.values.empty(),
               "a sweep needs a key and at least one value: --vary KEY=V1,V2,... (e.g. --vary training.seed=1,2,3)");
    for (const auto& v : opt.values)
        HINF_CHECK(!v.empty() && v.find(',') == std::string::npos, "--vary: empty value in the list for " + opt.key);
    {  // every value must make a valid config before any training starts (one line, every rank alike)
        for (const auto& v : opt.values) {
            ConfigDoc doc = ConfigDoc::from_file(config_path);
            for (const auto& s : opt.sets) doc.set(s);
            doc.set(opt.key + "=" + v);
            load_run_config(std::move(doc));
        }
    }
    std::filesystem::create_directories(opt.out_dir);
    const int V = int(opt.values.size());
    const int groups = std::min(V, par_world_size());
    const int group = par_split(groups);
    const bool group_root = par_root();
    std::vector<std::string> mine;  // "index,line" of the values this group trained (sent by its root)
    // the values of the world root's group: how many are done and the time left, from the values trained so far (one
    // finished by an earlier job takes no time and is not counted in the rate)
    const int of = (V - group + groups - 1) / groups;
    int done = 0, trained = 0;
    const auto start = std::chrono::steady_clock::now();
    for (int i = group; i < V; i += groups) {
        SweepRow r = train_value(config_path, opt, opt.values[i]);
        if (group_root) mine.push_back(std::to_string(i) + ',' + row_line(r));
        ++done;
        if (r.how != "done before") ++trained;
        if (opt.quiet || par_world_rank() != 0) continue;
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::string left = trained > 0 ? format_duration(elapsed / trained * (of - done)) : "-";
        std::fprintf(stderr, "sweep: %s=%s %s: status %d, training %s%s; %d/%d values%s done, elapsed %s, ETA %s\n",
                     opt.key.c_str(), r.value.c_str(), r.how.c_str(), r.summary.status,
                     format_duration(r.summary.wall_seconds).c_str(),
                     r.verdict.acceptance == "-" ? "" : (", acceptance " + r.verdict.acceptance).c_str(), done, of,
                     groups > 1 ? " of this process group" : "", format_duration(elapsed).c_str(), left.c_str());
        std::fflush(stderr);
    }
    par_unsplit();
    std::string text;
    for (const auto& m : mine) text += m + '\n';
    std::vector<SweepRow> rows(V);
    for (const auto& bytes : par_allgather(std::vector<char>(text.begin(), text.end()))) {
        std::stringstream in(std::string(bytes.begin(), bytes.end()));
        for (std::string line; std::getline(in, line);) {
            const std::size_t comma = line.find(',');
            const int i = std::stoi(line.substr(0, comma));
            rows[i] = parse_line(line.substr(comma + 1), "sweep");
            rows[i].dir = opt.out_dir + "/" + sweep_dir_name(opt.key, opt.values[i]);
        }
    }
    write_text_atomic(opt.out_dir + "/sweep.csv", [&](std::ostream& o) {
        o << "key," << kSummaryHeader << ",dir\n";
        for (const auto& r : rows) o << opt.key << ',' << row_line(r) << ',' << r.dir << '\n';
    });
    return rows;
}

}  // namespace hinf
