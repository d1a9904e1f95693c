#include "core/bench/variant_bench.h"

#include <fmt/core.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>

#include "core/bench/perf_suite.h"
#include "core/bench/window_kernels.h"
#include "core/common/error.h"

namespace marglab {
namespace {

// A variant's two kernels, whatever its scalar type. Each has its own WindowKernels so that
// neither sees the other's state.
struct Kernels {
  std::function<Status()> iteration, marginalization;
};

template <typename Scalar>
Kernels kernelsOf(const WindowSnapshot& w, const Variant& v) {
  auto it = std::make_shared<WindowKernels<Scalar>>(w, v);
  auto mg = std::make_shared<WindowKernels<Scalar>>(w, v);
  return {[it] { return it->iteration(); }, [mg, m = v.marg] { return mg->marginalize(m); }};
}

// As a timing candidate: it ran once without failing, so a failure now is a bug, not a result.
std::function<void()> timed(std::function<Status()> f, const std::string& what) {
  return [f = std::move(f), what] {
    if (!f().ok()) throw InputError("", 0, "bench: " + what + " failed on a repeat");
  };
}

// Σ over windows of one variant's field; NaN if it failed on any window.
double total(const VariantBench& b, size_t k, double VariantWindowTimes::*field) {
  double s = 0;
  for (const auto& w : b.times) {
    if (!w[k].failure.empty()) return std::numeric_limits<double>::quiet_NaN();
    s += w[k].*field;
  }
  return s;
}

int failures(const VariantBench& b, size_t k) {
  int n = 0;
  for (const auto& w : b.times) n += w[k].failure.empty() ? 0 : 1;
  return n;
}

// µs as the JSON keeps them: 6 significant digits, null when not measured.
Json measured(double x) { return std::isfinite(x) ? Json(roundedTo(x, 6)) : Json(nullptr); }

std::string us(double seconds) {
  return std::isfinite(seconds) ? fmt::format("{:.1f}", seconds * 1e6) : "–";
}
std::string ratio(double x, double reference) {
  const double r = x / reference;
  return std::isfinite(r) ? fmt::format("{:.2f}", r) : "–";
}

std::string windowRows(const VariantBench& b) {
  std::string s;
  for (size_t w = 0; w < b.windows.size(); ++w) {
    const VariantWindowTimes& ref = b.times[w].front();
    for (const VariantWindowTimes& t : b.times[w]) {
      if (!t.failure.empty()) {
        s += fmt::format("| {} | {} | failed: {} | | | |\n", b.windows[w], t.variant, t.failure);
        continue;
      }
      s += fmt::format("| {} | {} | {} | {} | {} | {} |\n", b.windows[w], t.variant,
                       us(t.iteration_s), ratio(t.iteration_s, ref.iteration_s),
                       us(t.marginalization_s), ratio(t.marginalization_s, ref.marginalization_s));
    }
  }
  return s;
}

}  // namespace

std::vector<VariantWindowTimes> timeVariants(const WindowSnapshot& window,
                                             const std::vector<Variant>& variants, int rounds,
                                             double batch_s) {
  std::vector<Variant> all = {Variant::parse(kBenchReferenceVariant)};
  for (const Variant& v : variants) {
    if (v.name() != all.front().name()) all.push_back(v);
  }
  std::vector<VariantWindowTimes> out(all.size());
  std::vector<std::function<void()>> candidates;
  std::vector<size_t> owner;  // candidates 2k, 2k+1 are out[owner[k]]'s
  for (size_t i = 0; i < all.size(); ++i) {
    out[i].variant = all[i].name();
    const Kernels k = all[i].precision == Precision::kF32 ? kernelsOf<float>(window, all[i])
                                                          : kernelsOf<double>(window, all[i]);
    Status s = k.iteration();
    if (s.ok()) s = k.marginalization();
    if (!s.ok()) {
      out[i].failure = s.message();
      continue;
    }
    candidates.push_back(timed(k.iteration, out[i].variant + " LM iteration"));
    candidates.push_back(timed(k.marginalization, out[i].variant + " marginalization"));
    owner.push_back(i);
  }
  const std::vector<double> t = timeSideBySide(candidates, rounds, batch_s);
  for (size_t k = 0; k < owner.size(); ++k) {
    out[owner[k]].iteration_s = t[2 * k];
    out[owner[k]].marginalization_s = t[2 * k + 1];
  }
  return out;
}

std::string variantBenchMarkdown(const VariantBench& b, const std::string& isa) {
  if (b.times.empty() || b.times.front().size() < 2) return "";
  std::string s = fmt::format(
      "## Chosen variants beside {0}: one LM iteration (linearize + eliminate + solve) and one "
      "marginalization event, µs, {1}\n\nRatio: the variant's time / {0}'s on the same window, "
      "timed side by side (> 1: slower).\n\n"
      "| window | variant | LM iteration | ratio | marginalization | ratio |\n"
      "|---|---|---:|---:|---:|---:|\n",
      kBenchReferenceVariant, isa);
  s += windowRows(b);
  const double ref_it = total(b, 0, &VariantWindowTimes::iteration_s);
  const double ref_mg = total(b, 0, &VariantWindowTimes::marginalization_s);
  for (size_t k = 0; k < b.times.front().size(); ++k) {
    const std::string& name = b.times.front()[k].variant;
    if (failures(b, k) > 0) {
      s += fmt::format("| **all** | {} | failed on {} of {} windows | | | |\n", name,
                       failures(b, k), b.windows.size());
      continue;
    }
    const double it = total(b, k, &VariantWindowTimes::iteration_s);
    const double mg = total(b, k, &VariantWindowTimes::marginalization_s);
    s += fmt::format("| **all** | {} | {} | **{}** | {} | **{}** |\n", name, us(it),
                     ratio(it, ref_it), us(mg), ratio(mg, ref_mg));
  }
  return s + "\n";
}

Json variantBenchJson(const VariantBench& b) {
  Json out = Json::array();
  if (b.times.empty()) return out;
  const double ref_it = total(b, 0, &VariantWindowTimes::iteration_s);
  const double ref_mg = total(b, 0, &VariantWindowTimes::marginalization_s);
  for (size_t k = 0; k < b.times.front().size(); ++k) {
    Json j;
    j["variant"] = b.times.front()[k].variant;
    const double it = total(b, k, &VariantWindowTimes::iteration_s);
    const double mg = total(b, k, &VariantWindowTimes::marginalization_s);
    j["lm_iteration_us"] = measured(it * 1e6);
    j["marginalization_us"] = measured(mg * 1e6);
    j["lm_iteration_ratio"] = measured(it / ref_it);
    j["marginalization_ratio"] = measured(mg / ref_mg);
    Json failed = Json::object();
    for (size_t w = 0; w < b.windows.size(); ++w) {
      if (!b.times[w][k].failure.empty()) failed[b.windows[w]] = b.times[w][k].failure;
    }
    j["failed_windows"] = failed;
    out.push_back(j);
  }
  return out;
}

}  // namespace marglab
