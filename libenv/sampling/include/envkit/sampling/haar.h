#pragma once
/// @file haar.h
/// The 2D Haar wavelet basis of Clarberg, Jarosz, Akenine-Moeller and Jensen, "Wavelet Importance Sampling:
/// Efficiently Evaluating Products of Complex Functions", SIGGRAPH 2005: the non-standard decomposition of an
/// R x R grid (R a power of two), its compression, and the product of two functions in the wavelet domain.
///
/// Basis. Orthonormal over the grid's cells (the discrete inner product sum a b): a 2 x 2 block (a b / c d) of
/// values or of scaling coefficients gives the scaling coefficient (a + b + c + d) / 2 and the details
/// (a - b + c - d) / 2 (horizontal), (a + b - c - d) / 2 (vertical), (a - b - c + d) / 2 (diagonal). So the
/// scaling coefficient of a node of k x k cells is its sum / k, and sum(a b) over the grid equals the sum of the
/// coefficients' products (Parseval).
/// Layout (in place, row-major): the non-standard pyramid. At the step of block size n (n = R, R / 2, .., 2) the
/// n / 2 x n / 2 nodes' scaling coefficients go to [0, n/2)^2 and node (i, j)'s details to (i + n/2, j)
/// (horizontal), (i, j + n/2) (vertical) and (i + n/2, j + n/2) (diagonal); the root's scaling coefficient ends at
/// index 0.
#include <cstddef>
#include <span>
#include <vector>

namespace envkit::haar {

/// Whether R is a power of two >= 2 (the sizes the transforms accept).
bool valid_size(int R);

/// Forward transform of the R x R values `v` (row-major), in place. Throws Error unless valid_size(R) and
/// v.size() == R x R.
void forward(std::span<double> v, int R);
/// Inverse of forward(), in place.
void inverse(std::span<double> c, int R);

/// The paper's lossy compression: keeps the scaling coefficient and the `keep` detail coefficients of largest
/// magnitude (ties to the lower index: deterministic), zeroing the others; keep <= 0 or >= R x R - 1 keeps all.
/// Returns the number of coefficients left non-zero.
std::size_t keep_largest(std::span<double> c, int R, int keep);

/// The product of two functions given by their coefficients (forward() of each), in the wavelet domain: for every
/// node of the quadtree, the sum over its cells of the pointwise product a x b, which is (orthonormality)
///     s_a(node) s_b(node) + sum over the detail coefficients d supported inside the node of a_d b_d
/// with s the node's scaling coefficients (found top-down). Returned as a pyramid: level 0 the R x R cells, level
/// k the (R >> k)^2 nodes, row-major, up to the 1 x 1 root (the product's integral over the grid's cells).
std::vector<std::vector<double>> product_sums(std::span<const double> a, std::span<const double> b, int R);

}  // namespace envkit::haar
