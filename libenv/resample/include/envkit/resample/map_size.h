#pragma once
/// @file map_size.h
/// Choosing an output size that keeps a map's texel density (what envconvert
/// does without --size).
#include <envkit/core/image.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/parameterization.h>

#include <cstddef>
#include <functional>
#include <optional>

namespace envkit {

/// Texels that hold data: all but those outside a ball's disk or in the blank
/// cells of a cross.
std::size_t data_texel_count(const Image& image, const Parameterization& param);

/// Natural size N (param_factory.h's natural_image_size) whose map of `kind`
/// holds about `texels` texels with data: the share of texels with data per N^2
/// is measured on a small map of that kind (6 for a cube, ~pi/4 for a ball); N
/// is rounded to a multiple of 8 from 64 up and clamped to [1, 2^17].
int matching_natural_size(std::size_t texels, Kind kind, const Convention& conv,
                          std::optional<CubeLayout> layout = std::nullopt);

/// The same for any output described by `spec_at(N)`, its spec at natural size N (camera views: N is the width,
/// the height follows the aspect). A map that sees only part of the sphere gets the input's density over the
/// solid angle it sees.
int matching_natural_size(std::size_t texels, const std::function<ParamSpec(int)>& spec_at);

}  // namespace envkit
