#include "core/estimator/variant.h"

#include <fmt/core.h>

#include <cstddef>
#include <sstream>

#include "core/common/enum_names.h"
#include "core/common/error.h"

namespace marglab {

namespace {

// The variant names: one table per axis. A storage is spelled representation + preconditioning
// + psd projection (the empty name is the axis' default), so a new value of an axis is one line
// here and its combinations with the other axes are named, parsed and checked by storageProblem.
inline constexpr EnumNames<OptElimination, 2> kOptNames{
    {{OptElimination::kNullspace, "ns"}, {OptElimination::kSchur, "sc"}}};
inline constexpr EnumNames<MargMethod, 2> kMargNames{
    {{MargMethod::kQr, "qr"}, {MargMethod::kSchur, "sc"}}};
inline constexpr EnumNames<Representation, 2> kRepresentationNames{
    {{Representation::kSqrt, "sqrt"}, {Representation::kHessian, "sq"}}};
inline constexpr EnumNames<Preconditioning, 3> kPreconditioningNames{
    {{Preconditioning::kNone, ""},
     {Preconditioning::kBlockJacobi, "p"},
     {Preconditioning::kJacobi, "j"}}};
inline constexpr EnumNames<PsdProjection, 3> kPsdNames{{{PsdProjection::kNone, ""},
                                                        {PsdProjection::kClampNegative, "c"},
                                                        {PsdProjection::kGaugeExact, "g"}}};
inline constexpr EnumNames<Precision, 3> kPrecisionNames{
    {{Precision::kF32, "f32"}, {Precision::kF64, "f64"}, {Precision::kMixed, "mixed"}}};

// The storage whose name is `text`; false if no combination of the axes' names spells it.
bool parseStorage(const std::string& text, PriorStorage* out) {
  for (const PriorStorage& s : storageCombinations()) {
    if (storageName(s) == text) {
      *out = s;
      return true;
    }
  }
  return false;
}

// The rules of the storage axes given the marginalization method.
std::string storageProblem(MargMethod marg, const PriorStorage& s) {
  if (marg == MargMethod::kQr && s != PriorStorage{}) {
    return "qr marginalization produces a square-root prior and requires storage sqrt (no "
           "preconditioning, no psd projection: the flat QR factorizes no Hessian)";
  }
  if (s.psd == PsdProjection::kClampNegative && sqrtStorage(s)) {
    return "psd projection c acts on a Hessian prior (sq); a square-root prior is positive "
           "semidefinite by construction";
  }
  return "";
}

// "none, p or j": a suffix axis, whose default is spelled as nothing.
template <typename E, std::size_t N>
std::string describeSuffixes(const EnumNames<E, N>& table) {
  EnumNames<E, N> shown = table;
  shown[0].name = "none";
  return describeNames(shown);
}

}  // namespace

std::string variantSyntax() {
  return "opt-marg-storage-precision with opt " + describeNames(kOptNames) + ", marg " +
         describeNames(kMargNames) + ", storage " + describeNames(kRepresentationNames) +
         " followed by a preconditioning (" + describeSuffixes(kPreconditioningNames) +
         ") and a psd projection (" + describeSuffixes(kPsdNames) + "), precision " +
         describeNames(kPrecisionNames) + " (e.g. ns-qr-sqrt-f32, sc-sc-sqpg-f32)";
}

std::string storageName(const PriorStorage& s) {
  return std::string(nameOf(kRepresentationNames, s.representation)) +
         nameOf(kPreconditioningNames, s.preconditioning) + nameOf(kPsdNames, s.psd);
}

std::vector<PriorStorage> storageCombinations() {
  std::vector<PriorStorage> all;
  for (const auto& representation : kRepresentationNames) {
    for (const auto& preconditioning : kPreconditioningNames) {
      for (const auto& psd : kPsdNames) {
        all.push_back({representation.value, preconditioning.value, psd.value});
      }
    }
  }
  return all;
}

std::string Variant::method() const {
  return fmt::format("{}-{}-{}", nameOf(kOptNames, opt), nameOf(kMargNames, marg),
                     storageName(storage));
}

std::string Variant::precisionName() const { return nameOf(kPrecisionNames, precision); }

std::string Variant::name() const { return method() + "-" + precisionName(); }

bool Variant::operator==(const Variant& other) const { return name() == other.name(); }

std::string variantProblem(const Variant& v) {
  if (v.precision == Precision::kMixed && v.opt != OptElimination::kNullspace) {
    return "mixed precision eliminates landmarks by nullspace projection (opt ns)";
  }
  return storageProblem(v.marg, v.storage);
}

Variant Variant::parse(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, '-');) parts.push_back(part);
  if (parts.size() != 4 || text.back() == '-') {  // getline drops a trailing ""
    throw UsageError(fmt::format("unknown variant '{}': expected {}", text, variantSyntax()));
  }
  auto bad = [&](const char* what, const std::string& part) {
    return UsageError(fmt::format("unknown variant '{}': bad {} '{}'; expected {}", text, what,
                                  part, variantSyntax()));
  };
  Variant v;
  if (!parseName(kOptNames, parts[0], &v.opt)) throw bad("opt", parts[0]);
  if (!parseName(kMargNames, parts[1], &v.marg)) throw bad("marg", parts[1]);
  if (!parseStorage(parts[2], &v.storage)) throw bad("storage", parts[2]);
  if (!parseName(kPrecisionNames, parts[3], &v.precision)) throw bad("precision", parts[3]);
  const std::string problem = variantProblem(v);
  if (!problem.empty()) throw UsageError(fmt::format("variant '{}': {}", text, problem));
  return v;
}

std::string psdHessianPriorProblem(const Variant& v) {
  if (sqrtStorage(v.storage)) {
    return "expected a Hessian prior storage (sq, sqp, sqj); a square-root prior is positive "
           "semidefinite by construction";
  }
  if (v.storage.psd != PsdProjection::kNone) {
    return fmt::format("the variant's storage {} names its psd projection already",
                       storageName(v.storage));
  }
  return "";
}

PriorStorage withPsdHessianPrior(PriorStorage storage, bool psd_hessian_prior) {
  if (psd_hessian_prior) storage.psd = PsdProjection::kClampNegative;
  return storage;
}

std::vector<Variant> paperVariants() {
  std::vector<Variant> variants;
  for (const char* method : {"ns-qr-sqrt", "sc-sc-sq", "sc-qr-sqrt", "ns-sc-sqrt", "sc-sc-sqrt"}) {
    for (const char* precision : {"f32", "f64"}) {
      variants.push_back(Variant::parse(std::string(method) + "-" + precision));
    }
  }
  return variants;
}

}  // namespace marglab
