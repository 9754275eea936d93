// validate(IntegratorOptions): each refused combination names its field, and the message spells options the way
// the caller asks (the library's field names, or a tool's flags).
#include <envkit/render/integrator.h>
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <string>

using namespace envkit;
using namespace envkit::render;
using F = IntegratorField;

namespace {

std::optional<IntegratorOptionsError> refusal(const IntegratorOptions& o) {
  try {
    validate(o);
  } catch (const IntegratorOptionsError& e) {
    return e;
  }
  return std::nullopt;
}

IntegratorOptions with(Strategy s) {
  IntegratorOptions o;
  o.strategy = s;
  return o;
}

std::string flag(IntegratorField f) { return std::string("--") + integrator_field_name(f); }

}  // namespace

TEST(IntegratorOptions, DefaultsAreValid) { EXPECT_FALSE(refusal(IntegratorOptions{}).has_value()); }

TEST(IntegratorOptions, EachRefusalNamesItsField) {
  struct Case {
    IntegratorOptions options;
    IntegratorField field;
  };
  std::vector<Case> cases;
  IntegratorOptions o;
  o.max_depth = 0;
  cases.push_back({o, F::MaxDepth});
  o = {};
  o.sun_samples = -1;
  cases.push_back({o, F::SunSamples});
  o = {};
  o.bsdf_samples = -1;
  cases.push_back({o, F::BsdfSamples});
  o = {};
  o.light_samples = -2;
  cases.push_back({o, F::LightSamples});
  o = with(Strategy::Bsdf);
  o.bsdf_samples = 0;
  cases.push_back({o, F::BsdfSamples});
  o = with(Strategy::Light);
  o.light_samples = 0;
  cases.push_back({o, F::LightSamples});
  o = with(Strategy::Mis);
  o.bsdf_samples = o.light_samples = 0;
  cases.push_back({o, F::Strategy});
  o = with(Strategy::MisCompensated);
  o.bsdf_samples = 0;
  cases.push_back({o, F::BsdfSamples});
  o = with(Strategy::Product);
  o.light_samples = 0;
  cases.push_back({o, F::LightSamples});
  o = with(Strategy::ProductMis);
  o.bsdf_samples = o.light_samples = 0;
  cases.push_back({o, F::Strategy});
  o = with(Strategy::Product);
  o.light_method = SamplingMethod::Alias;
  cases.push_back({o, F::LightMethod});
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const auto e = refusal(cases[i].options);
    ASSERT_TRUE(e.has_value()) << "case " << i;
    EXPECT_EQ(e->field, cases[i].field) << "case " << i << ": " << e->what();
  }
}

TEST(IntegratorOptions, MessagesSpellOptionsAsTheCallerAsks) {
  IntegratorOptions o;
  o.max_depth = 0;
  EXPECT_STREQ(refusal(o)->what(), "max_depth must be >= 1");
  EXPECT_EQ(refusal(o)->message(flag), "--max_depth must be >= 1");
  o = with(Strategy::ProductMis);
  o.light_method = SamplingMethod::Cdf;
  const auto e = refusal(o);
  EXPECT_EQ(std::string(e->what()),
            "light_method cdf: the product strategies refine the hierarchical table (another method needs strategy "
            "light, mis or mis-compensated)");
  EXPECT_EQ(e->message([](IntegratorField f) { return f == F::Strategy ? std::string("S") : std::string("M"); }),
            "M cdf: the product strategies refine the hierarchical table (another method needs S light, mis or "
            "mis-compensated)");
}

TEST(IntegratorOptions, TheSeedSamplersOptionsOutOfRangeNameTheirField) {
  struct Case {
    IntegratorOptions options;
    IntegratorField field;
    std::string message;
  };
  std::vector<Case> cases;
  IntegratorOptions o;
  o.wavelet.resolution = 48;
  cases.push_back({o, F::WaveletResolution, "wavelet.resolution 48: must be a power of two in 2..256"});
  o = {};
  o.wavelet.normal_bins = 0;
  cases.push_back({o, F::WaveletNormalBins, "wavelet.normal_bins 0: must be in 1..64"});
  o = {};
  o.wavelet.wo_bins = 65;
  cases.push_back({o, F::WaveletWoBins, "wavelet.wo_bins 65: must be in 1..64"});
  o = {};
  o.wavelet.kept_coefficients = -1;
  cases.push_back({o, F::WaveletKeptCoefficients, "wavelet.kept_coefficients -1: must be >= 0 (0 = all)"});
  o = {};
  o.steerable.order = 17;
  cases.push_back({o, F::SteerableOrder, "steerable.order 17: must be in 1..16"});
  o = {};
  o.steerable.resolution = 1024;
  cases.push_back({o, F::SteerableResolution, "steerable.resolution 1024: must be a power of two in 2..512"});
  o = {};
  o.sh.wo_bins = 1;
  cases.push_back({o, F::ShWoBins, "sh.wo_bins 1: must be in 2..256"});
  o = {};
  o.sh.defensive = 0.0;
  cases.push_back({o, F::ShDefensive, "sh.defensive 0: must be in (0, 1]"});
  o = {};
  o.steerable.defensive = std::nan("");
  cases.push_back({o, F::SteerableDefensive, "steerable.defensive nan: must be in (0, 1]"});
  for (const Case& c : cases) {
    const auto e = refusal(c.options);
    ASSERT_TRUE(e.has_value()) << c.message;
    EXPECT_EQ(e->field, c.field) << e->what();
    EXPECT_EQ(std::string(e->what()), c.message);
    EXPECT_EQ(e->message(flag), "--" + c.message);
  }
}
