// GGX radiance prefiltering: every level against the brute-force sum over every
// source texel, a 1e6 sun, constant maps, roughness mappings, octahedral output
// and thread-count independence.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <cstdlib>
#include <ctime>

#include "ibl/src/moment_tree.h"
#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;

namespace {

void print(const char* what, const LevelErrors& e, const PrefilteredChain& chain) {
  for (std::size_t i = 0; i < e.rms.size(); ++i)
    std::printf("%s level %zu alpha %.4f: rel RMS %.5f %.5f %.5f, max rel %.5f\n", what, i + 1, chain.alpha[i + 1],
                e.rms[i][0], e.rms[i][1], e.rms[i][2], e.max_rel[i]);
}

TEST(Prefilter, SmoothMapEveryLevelWithinHalfPercentOfBruteForce) {
  const EnvMap src = latlong_env(256, smooth_sky);
  PrefilterOptions o;
  o.size = 32;
  const PrefilteredChain chain = prefilter_ggx(src.ref(), o);
  ASSERT_EQ(chain.levels.size(), 6u);
  const LevelErrors e = compare_with_reference(src, chain);
  print("smooth", e, chain);
  for (std::size_t i = 0; i < e.rms.size(); ++i)
    for (int c = 0; c < 3; ++c) EXPECT_LE(e.rms[i][c], 0.005) << "level " << i + 1 << " channel " << c;
}

TEST(Prefilter, SunOfAMillionHasNoFireflies) {
  // A dim sky and one texel a million times brighter: the prefiltered levels
  // must follow the brute-force sum everywhere (a random-sample prefilter would
  // show isolated bright texels here).
  EnvMap src = latlong_env(256, [](const Vec3& d) { return Vec3(0.1 + 0.05 * d.y); });
  const int sx = 77, sy = 40;
  for (int c = 0; c < 3; ++c) src.image.at(sx, sy, c) = 1e6f;
  PrefilterOptions o;
  o.size = 32;
  const PrefilteredChain chain = prefilter_ggx(src.ref(), o);
  const LevelErrors e = compare_with_reference(src, chain);
  print("sun", e, chain);
  for (std::size_t i = 0; i < e.rms.size(); ++i) {
    EXPECT_LE(e.rms[i][0], 0.005) << "level " << i + 1;
    EXPECT_LE(e.max_rel[i], 0.03) << "level " << i + 1;
  }
}

// Sharp levels over a summed cube much finer than the output, the regime of a 2048 x 1024 map prefiltered to 256^2
// (nine levels, level 1 at alpha 1/64): the lobe's curvature term near its peak is large (w''/w ~ 1/alpha^4), so
// a node's variance must not come out of a difference of raw moments in float (it did: 7.7% relative RMS on the
// smooth map with Filament's mapping, 1.0% with the sun).
TEST(Prefilter, SharpLevelsOverAFineSourceCubeWithinHalfPercent) {
  EnvMap sun = latlong_env(512, [](const Vec3& d) { return Vec3(0.1 + 0.05 * d.y); });
  for (int c = 0; c < 3; ++c) sun.image.at(154, 80, c) = 1e6f;
  const EnvMap smooth = latlong_env(512, smooth_sky);
  struct Case {
    const char* name;
    const EnvMap* src;
    RoughnessMapping mapping;
  };
  for (const Case& k : {Case{"smooth, filament", &smooth, RoughnessMapping::Filament},
                        Case{"sun, gltf", &sun, RoughnessMapping::Gltf}}) {
    SCOPED_TRACE(k.name);
    PrefilterOptions o;
    o.size = 32;
    o.source_size = 256;
    o.mapping = k.mapping;
    const PrefilteredChain chain = prefilter_ggx(k.src->ref(), o);
    const LevelErrors e = compare_with_reference(*k.src, chain);
    print(k.name, e, chain);
    for (std::size_t i = 0; i < e.rms.size(); ++i) {
      for (int c = 0; c < 3; ++c) EXPECT_LE(e.rms[i][c], 0.005) << "level " << i + 1 << " channel " << c;
      EXPECT_LE(e.max_rel[i], 0.03) << "level " << i + 1;
    }
  }
}

// A short chain's sharpest level needs a summed cube much coarser than the output: the default source size stops
// at the first level whose nodes the walk never refines, with the accuracy of a full-size source.
TEST(Prefilter, SourceCubeSizedForTheSharpestLevel) {
  EnvMap sun = latlong_env(256, [](const Vec3& d) { return Vec3(0.1 + 0.05 * d.y); });
  for (int c = 0; c < 3; ++c) sun.image.at(77, 40, c) = 1e6f;
  PrefilterOptions o;
  o.size = 64;
  // Level 1 at alpha 0.25 refines nodes down to 0.2 x 0.5 rad (a 16^2 cube), level 2 at alpha 1 those across the
  // horizon down to 0.25 x 0.2 rad (32^2).
  o.levels = 3;
  const PrefilteredChain chain = prefilter_ggx(sun.ref(), o);
  EXPECT_EQ(chain.source_size, 32);
  o.source_size = 64;
  const PrefilteredChain full = prefilter_ggx(sun.ref(), o);
  const LevelErrors e = compare_with_reference(sun, chain), f = compare_with_reference(sun, full);
  print("sun, sized source", e, chain);
  print("sun, full source", f, full);
  for (std::size_t i = 0; i < e.rms.size(); ++i) {
    for (int c = 0; c < 3; ++c) EXPECT_LE(e.rms[i][c], 0.005) << "level " << i + 1 << " channel " << c;
    EXPECT_LE(e.max_rel[i], 0.03) << "level " << i + 1;
  }
}

// Short chains have sharp first levels (alpha 0.11 at 8^2 down to 0.02 at 128^2 with glTF's mapping) over a real
// HDRI's texture and sun: the summed cube must resolve the sharpest lobe, whatever the output size (256^2 is in the
// accuracy table of docs/PREFILTER.md).
TEST(Prefilter, SmallChainsOverATexturedMapWithinHalfPercent) {
  const EnvMap textured = textured_sky(256, 0.0f), sunny = textured_sky(256, 1e4f);
  for (int size : {8, 16, 32, 64, 128})
    for (const EnvMap* src : {&textured, &sunny}) {
      SCOPED_TRACE(std::to_string(size) + (src == &sunny ? " with a sun" : " textured"));
      PrefilterOptions o;
      o.size = size;
      const PrefilteredChain chain = prefilter_ggx(src->ref(), o);
      const LevelErrors e = compare_with_reference(*src, chain, 200);
      for (std::size_t i = 0; i < e.rms.size(); ++i)
        EXPECT_LE(worst_channel(e.rms[i]), 0.005)
            << "level " << i + 1 << " alpha " << chain.alpha[i + 1] << " source cube " << chain.source_size;
    }
}

// A summed cube far coarser than the lobes (a source_size asked for): the walk refines its finest nodes into their
// source texels, so every level still follows the brute-force sum.
TEST(Prefilter, CoarseSourceCubeRefinesIntoTexels) {
  const EnvMap sunny = textured_sky(256, 1e4f);
  PrefilterOptions o;
  o.size = 32;
  o.source_size = 8;
  const PrefilteredChain chain = prefilter_ggx(sunny.ref(), o);
  EXPECT_EQ(chain.source_size, 8);
  const LevelErrors e = compare_with_reference(sunny, chain, 200);
  print("sun, 8^2 source cube", e, chain);
  for (std::size_t i = 0; i < e.rms.size(); ++i) EXPECT_LE(worst_channel(e.rms[i]), 0.005) << "level " << i + 1;
}

// The unreal mapping's level 1 (alpha about 1e-3) is sharper than the source's texels, so the lobe alone would ask
// for a cube as fine as the source; the default cube stops where its tree reaches 4 times the source's bytes
// (a 256 x 128 RGB map: 32^2), and the texel lists keep the sharp levels exact over it.
TEST(Prefilter, SourceCubeMemoryCappedBySourceBytes) {
  const EnvMap sunny = textured_sky(256, 1e4f);
  PrefilterOptions o;
  o.size = 64;
  o.mapping = RoughnessMapping::Unreal;
  const PrefilteredChain chain = prefilter_ggx(sunny.ref(), o);
  EXPECT_EQ(chain.source_size, 32);
  const double source_bytes = double(sunny.image.texel_count()) * sunny.image.channels * sizeof(float);
  EXPECT_LE(detail::MomentTree::peak_bytes(chain.source_size), 4.0 * source_bytes);
  EXPECT_GT(detail::MomentTree::peak_bytes(2 * chain.source_size), 4.0 * source_bytes);
  const LevelErrors e = compare_with_reference(sunny, chain, 200);
  print("sun, unreal mapping, capped source cube", e, chain);
  for (std::size_t i = 0; i < e.rms.size(); ++i)
    EXPECT_LE(worst_channel(e.rms[i]), 0.005) << "level " << i + 1 << " alpha " << chain.alpha[i + 1];
}

TEST(Prefilter, ConstantMapStaysConstantAtEveryLevel) {
  const EnvMap src = latlong_env(64, [](const Vec3&) { return Vec3(0.25, 1.0, 3.0); });
  PrefilterOptions o;
  o.size = 16;
  for (Kind kind : {Kind::CubeMap, Kind::Octahedral}) {
    o.kind = kind;
    const PrefilteredChain chain = prefilter_ggx(src.ref(), o);
    for (const EnvMap& level : chain.levels)
      for (std::size_t i = 0; i < level.image.texel_count(); ++i) {
        EXPECT_NEAR(level.image.pixels[i * 3 + 0], 0.25, 0.25 * 1e-5);
        EXPECT_NEAR(level.image.pixels[i * 3 + 2], 3.0, 3.0 * 1e-5);
      }
  }
}

TEST(Prefilter, LevelZeroIsTheAreaResampledMap) {
  const EnvMap src = latlong_env(128, smooth_sky);
  PrefilterOptions o;
  o.size = 16;
  o.levels = 3;
  const PrefilteredChain chain = prefilter_ggx(src.ref(), o);
  ASSERT_EQ(chain.levels.size(), 3u);
  const CubeMap gl(16, CubeLayout::VerticalStrip, CubeBasis::GL);
  const Image direct = resample(src.ref(), gl, identity3());
  ASSERT_EQ(direct.pixels.size(), chain.levels[0].image.pixels.size());
  for (std::size_t i = 0; i < direct.pixels.size(); ++i) EXPECT_EQ(direct.pixels[i], chain.levels[0].image.pixels[i]);
  EXPECT_EQ(chain.levels[1].image.width, 8);
  EXPECT_EQ(chain.levels[2].image.height, 24);
  EXPECT_EQ(chain.levels[1].image.metadata.at("envkit:ibl_roughness_mapping"), "gltf");
}

TEST(Prefilter, OctahedralLevelsMatchBruteForce) {
  const EnvMap src = latlong_env(128, smooth_sky);
  PrefilterOptions o;
  o.kind = Kind::Octahedral;
  o.size = 32;
  o.levels = 4;
  const PrefilteredChain chain = prefilter_ggx(src.ref(), o);
  EXPECT_EQ(chain.levels[1].param->kind(), Kind::Octahedral);
  const LevelErrors e = compare_with_reference(src, chain);
  for (std::size_t i = 0; i < e.rms.size(); ++i)
    for (int c = 0; c < 3; ++c) EXPECT_LE(e.rms[i][c], 0.005) << "level " << i + 1;
}

TEST(Prefilter, RoughnessMappings) {
  // glTF-Sample-Viewer: linear in perceptual roughness.
  EXPECT_DOUBLE_EQ(level_roughness(RoughnessMapping::Gltf, 2, 9), 0.25);
  // Filament: lod = r (2 - r) inverted; lod 0.5 -> 1 - sqrt(0.5).
  EXPECT_NEAR(level_roughness(RoughnessMapping::Filament, 4, 9), 1.0 - std::sqrt(0.5), 1e-12);
  const double rf = level_roughness(RoughnessMapping::Filament, 3, 9);
  EXPECT_NEAR(rf * (2.0 - rf), 3.0 / 8.0, 1e-12);
  // Unreal: mip 1 from the 1x1 mip has roughness 1; one mip finer divides
  // roughness by 2^(1/1.2).
  EXPECT_DOUBLE_EQ(level_roughness(RoughnessMapping::Unreal, 7, 9), 1.0);
  EXPECT_NEAR(level_roughness(RoughnessMapping::Unreal, 6, 9), std::exp2(-1.0 / 1.2), 1e-12);
  EXPECT_DOUBLE_EQ(level_roughness(RoughnessMapping::Unreal, 8, 9), 1.0);
  EXPECT_EQ(parse_roughness_mapping("ue4"), RoughnessMapping::Unreal);
  EXPECT_THROW(parse_roughness_mapping("phong"), Error);
}

TEST(Prefilter, GgxDIntegratesToOneOverProjectedHalfVectors) {
  // int D(h) (n.h) d omega_h = 1 for every alpha (midpoint rule in cos theta).
  for (double alpha : {0.05, 0.3, 1.0}) {
    double sum = 0.0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      const double c = (i + 0.5) / n;
      sum += ggx_d(c, alpha) * c * kTwoPi / n;
    }
    EXPECT_NEAR(sum, 1.0, 2e-3) << alpha;
  }
}

TEST(Prefilter, IndependentOfThreadCount) {
  const EnvMap src = latlong_env(128, smooth_sky);
  PrefilterOptions o;
  o.size = 16;
  const PrefilteredChain many = prefilter_ggx(src.ref(), o);
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  const PrefilteredChain single = prefilter_ggx(src.ref(), o);
  for (std::size_t m = 0; m < many.levels.size(); ++m)
    EXPECT_EQ(many.levels[m].image.pixels, single.levels[m].image.pixels) << m;
}

TEST(Prefilter, RejectsBadOptions) {
  const EnvMap src = latlong_env(32, smooth_sky);
  PrefilterOptions o;
  o.size = 16;
  o.levels = 6;
  EXPECT_THROW(prefilter_ggx(src.ref(), o), Error);
  o.levels = 0;
  o.source_size = 24;
  EXPECT_THROW(prefilter_ggx(src.ref(), o), Error);
  o.source_size = 0;
  o.kind = Kind::LatLong;
  EXPECT_THROW(prefilter_ggx(src.ref(), o), Error);
}

}  // namespace
