#pragma once
/// @file render_options.h
/// What envrender and envproduct share on the command line: the seed samplers' parameters as options, and the flag
/// each IntegratorOptions field comes from (so that the library's refusals name what the user typed).
#include <envkit/render/integrator.h>

#include <CLI/CLI.hpp>
#include <string>

namespace envkit::render::cli {

/// Adds --wavelet-*, --steerable-* and --sh-* (IntegratorOptions' wavelet, steerable and sh), each with its paper and
/// its range in the help; values go straight into `options` and are range-checked by validate() (the tool maps the
/// refusal's field to its flag with option_flag()). CLI11 refuses only what is not a number.
void add_seed_sampler_options(CLI::App& app, IntegratorOptions& options);

/// The option an IntegratorOptions field comes from ("--max-depth", "--sh-order").
std::string option_flag(IntegratorField field);

}  // namespace envkit::render::cli
