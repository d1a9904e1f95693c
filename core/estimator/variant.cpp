#include "core/estimator/variant.h"

#include <fmt/core.h>

#include <sstream>

#include "core/common/error.h"

namespace marglab {

namespace {

const char* storageName(PriorStorage storage) {
  switch (storage) {
    case PriorStorage::kSqrt:
      return "sqrt";
    case PriorStorage::kHessian:
      return "sq";
    case PriorStorage::kHessianBlockJacobi:
      return "sqp";
    case PriorStorage::kHessianJacobi:
      return "sqj";
    case PriorStorage::kSqrtBlockJacobi:
      return "sqrtp";
  }
  return "";
}

}  // namespace

std::string Variant::method() const {
  return fmt::format("{}-{}-{}", opt == OptElimination::kNullspace ? "ns" : "sc",
                     marg == MargMethod::kQr ? "qr" : "sc", storageName(storage));
}

std::string Variant::precisionName() const {
  switch (precision) {
    case Precision::kF32:
      return "f32";
    case Precision::kF64:
      return "f64";
    case Precision::kMixed:
      return "mixed";
  }
  return "";
}

std::string Variant::name() const { return method() + "-" + precisionName(); }

bool Variant::operator==(const Variant& other) const { return name() == other.name(); }

Variant Variant::parse(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, '-');) parts.push_back(part);
  const std::string expected =
      "expected opt-marg-storage-precision with opt ns|sc, marg qr|sc, storage sqrt|sq|sqp|sqj|sqrtp, "
      "precision f32|f64|mixed (e.g. ns-qr-sqrt-f32; mixed needs opt ns)";
  if (parts.size() != 4) {
    throw UsageError(fmt::format("unknown variant '{}': {}", text, expected));
  }
  auto bad = [&](const std::string& what) {
    return UsageError(fmt::format("unknown variant '{}': bad {}; {}", text, what, expected));
  };
  Variant v;
  if (parts[0] == "ns") {
    v.opt = OptElimination::kNullspace;
  } else if (parts[0] == "sc") {
    v.opt = OptElimination::kSchur;
  } else {
    throw bad("opt '" + parts[0] + "'");
  }
  if (parts[1] == "qr") {
    v.marg = MargMethod::kQr;
  } else if (parts[1] == "sc") {
    v.marg = MargMethod::kSchur;
  } else {
    throw bad("marg '" + parts[1] + "'");
  }
  if (parts[2] == "sqrt") {
    v.storage = PriorStorage::kSqrt;
  } else if (parts[2] == "sq") {
    v.storage = PriorStorage::kHessian;
  } else if (parts[2] == "sqp") {
    v.storage = PriorStorage::kHessianBlockJacobi;
  } else if (parts[2] == "sqj") {
    v.storage = PriorStorage::kHessianJacobi;
  } else if (parts[2] == "sqrtp") {
    v.storage = PriorStorage::kSqrtBlockJacobi;
  } else {
    throw bad("storage '" + parts[2] + "'");
  }
  if (parts[3] == "f32") {
    v.precision = Precision::kF32;
  } else if (parts[3] == "f64") {
    v.precision = Precision::kF64;
  } else if (parts[3] == "mixed") {
    v.precision = Precision::kMixed;
  } else {
    throw bad("precision '" + parts[3] + "'");
  }
  if (v.marg == MargMethod::kQr && v.storage != PriorStorage::kSqrt) {
    throw UsageError(fmt::format(
        "variant '{}': qr marginalization produces a square-root prior and requires storage sqrt",
        text));
  }
  if (v.precision == Precision::kMixed && v.opt != OptElimination::kNullspace) {
    throw UsageError(fmt::format(
        "variant '{}': mixed precision eliminates landmarks by nullspace projection (opt ns)", text));
  }
  return v;
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
