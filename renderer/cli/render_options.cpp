#include "render_options.h"

#include <climits>

#include "common/cli.h"

namespace envkit::render::cli {

namespace {

constexpr const char* kWavelet =
    "product-wavelet(-mis) (Clarberg, Jarosz, Akenine-Moller and Jensen 2005, "
    "\"Wavelet Importance Sampling\"): ";
constexpr const char* kSteerable = "product-steerable(-mis) (Subr and Arvo 2007, \"Steerable Importance Sampling\"): ";
constexpr const char* kSh =
    "product-sh(-mis) (Jarosz, Carr and Jensen 2009, \"Importance Sampling Spherical "
    "Harmonics\"): ";

/// An integer whose range validate() checks (CLI11 only refuses what is not an integer).
CLI::Option* integer(CLI::App& app, const std::string& flag, int& value, const std::string& help) {
  return app.add_option(flag, value, help)
      ->transform(tools::integer_in(INT_MIN, INT_MAX).description(""))
      ->capture_default_str();
}

/// The three options the two basis samplers share, under `prefix` ("--steerable", "--sh").
void add_basis_options(CLI::App& app, const std::string& prefix, const char* paper, BasisProductOptions& o,
                       const std::string& order_help) {
  integer(app, prefix + "-order", o.order, std::string(paper) + order_help + ", 1..16");
  integer(app, prefix + "-resolution", o.resolution,
          std::string(paper) + "finest cells per side of the sphere's equal-area square, a power of two in 2..512");
  integer(app, prefix + "-wo-bins", o.wo_bins,
          std::string(paper) + "outgoing elevations of each material's fitted BSDF x cos, 2..256");
  app.add_option(prefix + "-defensive", o.defensive,
                 std::string(paper) + "share of the plain environment table in each point's mixture, in (0, 1]")
      ->check(tools::number_in(-1e300, 1e300).description(""))
      ->capture_default_str();
}

}  // namespace

void add_seed_sampler_options(CLI::App& app, IntegratorOptions& o) {
  integer(app, "--wavelet-resolution", o.wavelet.resolution,
          std::string(kWavelet) + "cells per side R of the hemisphere's square, a power of two in 2..256");
  integer(app, "--wavelet-normal-bins", o.wavelet.normal_bins,
          std::string(kWavelet) + "lighting bins per side of the octahedral grid of normals, 1..64");
  integer(app, "--wavelet-wo-bins", o.wavelet.wo_bins,
          std::string(kWavelet) + "BSDF slices per side of the square of outgoing directions, 1..64");
  integer(app, "--wavelet-kept", o.wavelet.kept_coefficients,
          std::string(kWavelet) +
              "detail coefficients kept per factor (the paper's compression, largest first), >= 0; 0 = all");
  add_basis_options(app, "--steerable", kSteerable, o.steerable,
                    "highest SH band of the steering function (the fitted BSDF x cos)");
  add_basis_options(app, "--sh", kSh, o.sh, "highest SH band of the lighting and of the fitted BSDF x cos");
}

std::string option_flag(IntegratorField field) {
  using F = IntegratorField;
  switch (field) {
    case F::Strategy:
      return "--strategy";
    case F::LightMethod:
      return "--light-method";
    case F::BsdfSamples:
      return "--bsdf-samples";
    case F::LightSamples:
      return "--light-samples";
    case F::SunSamples:
      return "--sun-samples";
    case F::MaxDepth:
      return "--max-depth";
    case F::Regularization:
      return "--regularize";
    case F::WaveletResolution:
      return "--wavelet-resolution";
    case F::WaveletNormalBins:
      return "--wavelet-normal-bins";
    case F::WaveletWoBins:
      return "--wavelet-wo-bins";
    case F::WaveletKeptCoefficients:
      return "--wavelet-kept";
    case F::SteerableOrder:
      return "--steerable-order";
    case F::SteerableResolution:
      return "--steerable-resolution";
    case F::SteerableWoBins:
      return "--steerable-wo-bins";
    case F::SteerableDefensive:
      return "--steerable-defensive";
    case F::ShOrder:
      return "--sh-order";
    case F::ShResolution:
      return "--sh-resolution";
    case F::ShWoBins:
      return "--sh-wo-bins";
    case F::ShDefensive:
      return "--sh-defensive";
  }
  return "?";
}

}  // namespace envkit::render::cli
