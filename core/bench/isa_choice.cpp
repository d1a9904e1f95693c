#include "core/bench/isa_choice.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <unistd.h>

#include <toml++/toml.h>
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <sstream>

#include "core/bench/window_kernels.h"
#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/data/sequence.h"
#include "core/estimator/window_io.h"
#include "marglab/version.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

constexpr double kTieFraction = 0.01;  // within 1 % of the fastest: the narrower ISA
constexpr int kRepetitions = 9;

const char* const kProbeWindows[] = {"euroc-MH_01_easy_ns-qr-sqrt-f32_000600.win.gz",
                                     "kitti-00_ns-qr-sqrt-f32_000500.win.gz"};

// One probe iteration with one ISA's code (a linearization keeps the ISA it was made with).
template <typename Scalar>
std::function<void()> probe(Isa isa, const WindowSnapshot& window, const char* variant) {
  setActiveIsa(isa);
  auto kernels = std::make_shared<WindowKernels<Scalar>>(window, Variant::parse(variant));
  return [kernels] { (void)kernels->iteration(); };  // a failed solve costs its time all the same
}

double secondsOf(const std::function<void()>& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(line.find_first_not_of(' ', colon + 1));
    }
  }
  return "unknown CPU";
}

// The cache's key: the CPU, the build, and the ISAs this build and CPU offer.
std::string cacheKey(const std::vector<Isa>& isas) {
  std::string names;
  for (const Isa isa : isas) names += std::string(names.empty() ? "" : ",") + isaName(isa);
  return fmt::format("{} | {} | {}", cpuModel(), MARGLAB_GIT_SHA, names);
}

std::string describe(const std::vector<IsaTiming>& timings) {
  std::vector<std::string> parts;
  for (const IsaTiming& t : timings) {
    parts.push_back(fmt::format("{} {:.2f} ms", isaName(t.isa), 1e3 * t.seconds));
  }
  return fmt::format("{}", fmt::join(parts, ", "));
}

// An exclusive flock(2) on <cache>.lock while it lives; no lock when the folder is not writable.
class CacheLock {
 public:
  explicit CacheLock(const std::string& cache) {
    std::error_code ec;
    fs::create_directories(fs::path(cache).parent_path(), ec);
    fd_ = ::open((cache + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ >= 0 && ::flock(fd_, LOCK_EX) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~CacheLock() {
    if (fd_ >= 0) ::close(fd_);  // closing releases the lock
  }
  CacheLock(const CacheLock&) = delete;
  CacheLock& operator=(const CacheLock&) = delete;
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

toml::table readCache(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return {};
  try {
    return toml::parse_file(path);
  } catch (const toml::parse_error&) {
    return {};  // a damaged cache is measured again and rewritten
  }
}

std::optional<Isa> cachedIsa(const toml::table& cache, const std::string& key,
                             std::vector<IsaTiming>* timings) {
  const toml::table* entry = cache[key].as_table();
  if (entry == nullptr) return std::nullopt;
  const std::optional<std::string> name = (*entry)["isa"].value<std::string>();
  std::optional<Isa> chosen;
  for (const Isa isa : kAllIsas) {
    if (name && *name == isaName(isa) && isaAvailable(isa)) chosen = isa;
    if (const auto s = (*entry)["ms"][isaName(isa)].value<double>()) {
      timings->push_back({isa, *s / 1e3});
    }
  }
  return chosen;
}

void writeCache(const std::string& path, toml::table cache, const std::string& key,
                const IsaChoice& choice) {
  toml::table ms;
  for (const IsaTiming& t : choice.timings) ms.insert(isaName(t.isa), 1e3 * t.seconds);
  cache.insert_or_assign(key, toml::table{{"isa", isaName(choice.isa)}, {"ms", ms}});
  std::ostringstream text;
  text << "# marglab --isa auto: the measured choice per CPU and build (core/bench/isa_choice.h)\n"
       << cache << "\n";
  AtomicFile file(path);
  file.write(text.str());
  file.commit();
}

}  // namespace

std::vector<IsaTiming> timeIsas(int repetitions) {
  const Isa active = activeIsa();
  std::vector<WindowSnapshot> windows;
  for (const char* name : kProbeWindows) {
    windows.push_back(readWindow((fs::path(datasetsRoot()) / "windows" / name).string()));
  }
  std::vector<IsaTiming> out;
  std::vector<std::vector<std::function<void()>>> probes;
  for (const Isa isa : availableIsas()) {
    out.push_back({isa, 0});
    probes.emplace_back();
    for (const WindowSnapshot& window : windows) {
      probes.back().push_back(probe<float>(isa, window, "ns-qr-sqrt-f32"));
      probes.back().push_back(probe<double>(isa, window, "sc-sc-sq-f64"));
    }
  }
  setActiveIsa(active);
  const std::size_t n = probes.empty() ? 0 : probes.front().size();
  for (std::size_t p = 0; p < n; ++p) {
    std::vector<double> best(out.size(), 1e300);
    for (int r = 0; r < repetitions; ++r) {
      for (std::size_t i = 0; i < out.size(); ++i) {
        best[i] = std::min(best[i], secondsOf(probes[i][p]));
      }
    }
    for (std::size_t i = 0; i < out.size(); ++i) out[i].seconds += best[i];
  }
  return out;
}

Isa fastestIsa(const std::vector<IsaTiming>& timings) {
  if (timings.empty()) return bestIsa();
  double fastest = 1e300;
  for (const IsaTiming& t : timings) fastest = std::min(fastest, t.seconds);
  for (const IsaTiming& t : timings) {  // kAllIsas order: narrowest first
    if (t.seconds <= fastest * (1 + kTieFraction)) return t.isa;
  }
  return timings.front().isa;
}

std::string isaCachePath() {
  if (const char* path = std::getenv("MARGLAB_ISA_CACHE"); path != nullptr && *path != '\0') {
    return path;
  }
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg == '/') {
    return (fs::path(xdg) / "marglab" / "isa_choice.toml").string();
  }
  const char* home = std::getenv("HOME");
  return (fs::path(home != nullptr && *home != '\0' ? home : "/tmp") / ".cache" / "marglab" /
          "isa_choice.toml")
      .string();
}

IsaChoice chooseAutoIsa() {
  const std::vector<Isa> isas = availableIsas();
  if (isas.size() == 1) return {isas.front(), {}, "auto: the only ISA available"};
  const std::string path = isaCachePath(), key = cacheKey(isas);
  const CacheLock lock(path);
  const toml::table cache = readCache(path);
  IsaChoice choice;
  if (const std::optional<Isa> cached = cachedIsa(cache, key, &choice.timings)) {
    choice.isa = *cached;
    choice.how =
        fmt::format("auto: measured fastest ({}), cached in {}", describe(choice.timings), path);
    return choice;
  }
  choice.timings = timeIsas(kRepetitions);
  choice.isa = fastestIsa(choice.timings);
  choice.how = fmt::format("auto: measured fastest ({})", describe(choice.timings));
  try {
    if (!lock.held()) throw InputError(path, 0, "cannot lock the cache");
    writeCache(path, cache, key, choice);
    choice.how += ", cached in " + path;
  } catch (const InputError& e) {
    choice.how += fmt::format(", not cached ({})", e.what());
  }
  return choice;
}

void activateIsa(const std::string& name) {
  if (name != "auto") {
    setActiveIsa(resolveIsa(name), "--isa " + name);
    return;
  }
  const IsaChoice choice = chooseAutoIsa();
  setActiveIsa(choice.isa, choice.how);
}

}  // namespace marglab
