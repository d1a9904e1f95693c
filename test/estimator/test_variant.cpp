// The variant names as axes (docs/design.md §2): every name in use keeps its meaning, every valid
// combination of the axes round-trips through its name, and the rules refuse the others.

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "core/common/error.h"
#include "core/estimator/variant.h"

namespace marglab {
namespace {

// The storage names of the variants before the axes, with the axis values they always meant.
TEST(VariantAxes, NamesInUseKeepTheirMeaning) {
  const Representation kS = Representation::kSqrt, kH = Representation::kHessian;
  const Preconditioning kNo = Preconditioning::kNone, kBj = Preconditioning::kBlockJacobi;
  const struct {
    const char* name;
    PriorStorage storage;
  } expected[] = {{"ns-qr-sqrt-f32", {kS}},       {"sc-sc-sq-f64", {kH}},
                  {"sc-sc-sqp-f32", {kH, kBj}},   {"sc-sc-sqj-f32", {kH, Preconditioning::kJacobi}},
                  {"sc-sc-sqrtp-f32", {kS, kBj}}, {"ns-sc-sqrt-mixed", {kS, kNo}},
                  {"sc-qr-sqrt-f64", {kS}}};
  for (const auto& e : expected) {
    const Variant v = Variant::parse(e.name);
    EXPECT_EQ(v.name(), e.name);
    EXPECT_EQ(v.storage, e.storage) << e.name;
    EXPECT_EQ(v.storage.psd, PsdProjection::kNone) << e.name;
  }
  EXPECT_EQ(Variant::parse("ns-qr-sqrt-mixed").precision, Precision::kMixed);
}

// Every combination of opt, marg, the storage axes and precision is either a variant whose name
// parses back to it, or refused by parse with the rule variantProblem names; the names are unique.
TEST(VariantAxes, EveryCombinationRoundTripsOrIsRefused) {
  std::set<std::string> names;
  int valid = 0;
  for (OptElimination opt : {OptElimination::kNullspace, OptElimination::kSchur}) {
    for (MargMethod marg : {MargMethod::kQr, MargMethod::kSchur}) {
      for (const PriorStorage& storage : storageCombinations()) {
        for (Precision precision : {Precision::kF32, Precision::kF64, Precision::kMixed}) {
          const Variant v{opt, marg, storage, precision};
          EXPECT_TRUE(names.insert(v.name()).second) << v.name();
          if (variantProblem(v).empty()) {
            ++valid;
            EXPECT_EQ(Variant::parse(v.name()), v);
          } else {
            EXPECT_THROW(Variant::parse(v.name()), UsageError) << v.name();
          }
        }
      }
    }
  }
  // qr: sqrt only (ns, sc × 3 precisions but sc-mixed: 5); sc: 18 storages less sqrtc, sqrtpc,
  // sqrtjc (psd c is for Hessians) = 15, × 5 opt-precision pairs = 75.
  EXPECT_EQ(valid, 5 + 75);
}

TEST(VariantAxes, RulesNameTheirReason) {
  EXPECT_THROW(Variant::parse("ns-qr-sq-f32"), UsageError);
  EXPECT_THROW(Variant::parse("ns-qr-sqrtg-f32"), UsageError);
  EXPECT_THROW(Variant::parse("sc-sc-sqx-f32"), UsageError);
  const Variant sqrt_c{
      OptElimination::kSchur,
      MargMethod::kSchur,
      {Representation::kSqrt, Preconditioning::kNone, PsdProjection::kClampNegative},
      Precision::kF32};
  EXPECT_NE(variantProblem(sqrt_c).find("positive semidefinite by construction"),
            std::string::npos);
  EXPECT_NE(variantProblem({OptElimination::kSchur, MargMethod::kQr, {}, Precision::kMixed})
                .find("nullspace"),
            std::string::npos);
}

// [marginalization] psd_hessian_prior is the psd axis `c` on a variant named without one.
TEST(VariantAxes, PsdHessianPriorIsTheClampProjection) {
  const Variant sq = Variant::parse("sc-sc-sq-f32");
  EXPECT_EQ(withPsdHessianPrior(sq.storage, true), Variant::parse("sc-sc-sqc-f32").storage);
  EXPECT_EQ(withPsdHessianPrior(Variant::parse("sc-sc-sqp-f32").storage, true),
            Variant::parse("sc-sc-sqpc-f32").storage);
  EXPECT_EQ(withPsdHessianPrior(sq.storage, false), sq.storage);
  EXPECT_TRUE(psdHessianPriorProblem(sq).empty());
  EXPECT_FALSE(psdHessianPriorProblem(Variant::parse("sc-sc-sqrt-f32")).empty());
  EXPECT_FALSE(psdHessianPriorProblem(Variant::parse("sc-sc-sqg-f32")).empty());
}

}  // namespace
}  // namespace marglab
