#include "core/ba/ba_results.h"

#include <sys/resource.h>

#include <utility>
#include <vector>

#include "core/common/error.h"
#include "core/common/utc_time.h"
#include "core/io/hdf5.h"
#include "core/io/hdf5_trust.h"
#include "core/linalg/isa.h"
#include "marglab/version.h"

namespace marglab {
namespace {

constexpr int kBaSchemaVersion = 2;  // 2: isa, isa_choice, total_cpu_s, /iterations/cpu_s

void writeSettings(const h5::File& file, const BaRunRecord& run) {
  const BaOptions& o = run.options;
  file.setAttr("kind", "ba");
  file.setAttr("schema_version", kBaSchemaVersion);
  file.setAttr("marglab_version", MARGLAB_VERSION_STRING);
  file.setAttr("git_sha", MARGLAB_GIT_SHA);
  file.setAttr("created_utc", utcNowIso8601());
  file.setAttr("problem", run.problem->name);
  file.setAttr("problem_file", run.problem_file);
  file.setAttr("num_cameras", run.problem->numCameras());
  file.setAttr("num_points", run.problem->numPoints());
  file.setAttr("num_observations", run.problem->numObservations());
  file.setAttr("solver", toString(o.solver));
  file.setAttr("precision", precisionOf(o.solver));
  file.setAttr("iterations", o.iterations);
  file.setAttr("huber_px", o.huber_px);
  file.setAttr("perturb_sigma", o.perturb_sigma);
  file.setAttr("seed", static_cast<std::int64_t>(o.seed));
  file.setAttr("normalize_scale", o.normalize_scale);
  file.setAttr("initial_lambda", o.initial_lambda);
  file.setAttr("min_lambda", o.min_lambda);
  file.setAttr("max_lambda", o.max_lambda);
  file.setAttr("function_tolerance", o.function_tolerance);
  file.setAttr("cg_max_iterations", o.cg.max_iterations);
  file.setAttr("cg_eta", o.cg.eta);
  file.setAttr("threads", o.threads);
  // The kernels of ns / sc (core/linalg/isa.h); Ceres is built for the baseline whatever it says.
  file.setAttr("isa", isaName(activeIsa()));
  file.setAttr("isa_choice", activeIsaChoice());
}

void writeOutcome(const h5::File& file, const BaRunRecord& run) {
  const BaResult& r = run.result;
  file.setAttr("initial_cost", r.initial_cost);
  file.setAttr("final_cost", r.final_cost);
  file.setAttr("status", r.status);
  file.setAttr("status_reason", r.reason);
  file.setAttr("num_behind_initial", r.num_behind_initial);
  file.setAttr("num_behind_final", r.num_behind_final);
  file.setAttr("num_fixed_points", r.num_fixed_points);
  file.setAttr("total_time_s", r.total_time_s);
  file.setAttr("total_cpu_s", r.total_cpu_s);
  file.setAttr("peak_rss_mb", run.peak_rss_mb);
}

void writeIterations(const h5::File& file, const std::vector<BaIteration>& rows) {
  std::vector<std::int64_t> iteration, cg_iterations;
  std::vector<std::uint8_t> accepted;
  std::vector<double> cost, time_s, cpu_s, lambda, ritz_min, ritz_max;
  std::vector<std::string> messages;
  for (const BaIteration& row : rows) {
    iteration.push_back(row.iteration);
    cost.push_back(row.cost);
    time_s.push_back(row.time_s);
    cpu_s.push_back(row.cpu_s);
    lambda.push_back(row.lambda);
    cg_iterations.push_back(row.cg_iterations);
    accepted.push_back(row.accepted ? 1 : 0);
    ritz_min.push_back(row.ritz_min);
    ritz_max.push_back(row.ritz_max);
    messages.push_back(row.message);
  }
  const h5::Group g = file.group("iterations");
  g.write("iteration", iteration);
  g.write("cost", cost);
  g.write("time_s", time_s);
  g.write("cpu_s", cpu_s);
  g.write("lambda", lambda);
  g.write("cg_iterations", cg_iterations);
  g.write("accepted", accepted);
  g.write("ritz_min", ritz_min);
  g.write("ritz_max", ritz_max);
  g.setAttr("messages", messages);
}

}  // namespace

void writeBaResults(const std::string& path, const BaRunRecord& run) {
  h5::File file = h5::File::create(path);
  writeSettings(file, run);
  writeOutcome(file, run);
  writeIterations(file, run.result.iterations);
  file.commit();
}

Json baResultJson(const BaRunRecord& run) {
  Json j;
  j["problem"] = run.problem->name;
  j["solver"] = toString(run.options.solver);
  j["status"] = run.result.status;
  j["status_reason"] = run.result.reason;
  j["initial_cost"] = run.result.initial_cost;
  j["final_cost"] = run.result.final_cost;
  j["total_time_s"] = run.result.total_time_s;
  j["peak_rss_mb"] = run.peak_rss_mb;
  Json iterations = Json::array();
  for (const BaIteration& row : run.result.iterations) {
    iterations.push_back({{"cost", row.cost}, {"time_s", row.time_s}});
  }
  j["iterations"] = std::move(iterations);
  return j;
}

namespace {

BaResultsFile readBaResultsUntrusted(const std::string& path) {
  const h5::File file = h5::File::openReadOnly(path);
  if (!file.hasAttr("kind") || file.attr<std::string>("kind") != "ba") {
    throw InputError(path, 0, "not a `marglab ba` results file (no root attribute kind = \"ba\")");
  }
  BaResultsFile r;
  if (file.hasAttr("isa")) r.isa = file.attr<std::string>("isa");  // "" before the attribute
  for (auto [name, value] : {std::pair{"git_sha", &r.git_sha},
                             {"problem", &r.problem},
                             {"problem_file", &r.problem_file},
                             {"solver", &r.solver},
                             {"precision", &r.precision},
                             {"status", &r.status},
                             {"status_reason", &r.status_reason}}) {
    *value = file.attr<std::string>(name);
  }
  for (auto [name, value] : {std::pair{"num_cameras", &r.num_cameras},
                             {"num_points", &r.num_points},
                             {"num_observations", &r.num_observations},
                             {"iterations", &r.max_iterations},
                             {"threads", &r.threads}}) {
    *value = static_cast<int>(file.attr<std::int64_t>(name));
  }
  r.seed = static_cast<std::uint64_t>(file.attr<std::int64_t>("seed"));
  for (auto [name, value] : {std::pair{"huber_px", &r.huber_px},
                             {"perturb_sigma", &r.perturb_sigma},
                             {"normalize_scale", &r.normalize_scale},
                             {"initial_cost", &r.initial_cost},
                             {"final_cost", &r.final_cost},
                             {"total_time_s", &r.total_time_s},
                             {"peak_rss_mb", &r.peak_rss_mb}}) {
    *value = file.attr<double>(name);
  }
  const h5::Group g = file.openGroup("iterations");
  const auto iteration = g.readVector<std::int64_t>("iteration");
  const auto cg = g.readVector<std::int64_t>("cg_iterations");
  const auto accepted = g.readVector<std::uint8_t>("accepted");
  const auto cost = g.readVector<double>("cost"), time_s = g.readVector<double>("time_s");
  const auto lambda = g.readVector<double>("lambda");
  const auto ritz_min = g.readVector<double>("ritz_min"),
             ritz_max = g.readVector<double>("ritz_max");
  const auto messages = g.attr<std::vector<std::string>>("messages");
  const std::size_t n = iteration.size();
  for (const std::size_t size :
       {cg.size(), accepted.size(), cost.size(), time_s.size(), lambda.size(), ritz_min.size(),
        ritz_max.size(), messages.size()}) {
    if (size != n) throw InputError(path, 0, "/iterations: columns of different lengths");
  }
  for (std::size_t i = 0; i < n; ++i) {
    r.iterations.push_back({static_cast<int>(iteration[i]), cost[i], time_s[i], lambda[i],
                            static_cast<int>(cg[i]), accepted[i] != 0, ritz_min[i], ritz_max[i],
                            messages[i]});
  }
  return r;
}

}  // namespace

BaResultsFile readBaResults(const std::string& path) {
  h5::checkReadableInChild(path, [&path] { readBaResultsUntrusted(path); });
  return readBaResultsUntrusted(path);
}

double peakResidentMb() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return -1;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

}  // namespace marglab
