// The pyramid's group descent over vectors of lanes, written once for every instruction set: included by
// distribution_hierarchical_avx2.cpp and distribution_hierarchical_avx512.cpp (no include guard), each inside its own
// namespace after defining
//   ENVKIT_LANES_TARGET   the target attribute of the functions below;
//   struct Lanes          kWidth, the types D (kWidth doubles), I (kWidth int64) and M (a mask of lanes), and
//                         loadd/stored/loadi/storei, setd/seti, add/sub/mul/div/min (D), select(m, a, b) (m ? b : a),
//                         not_less(a, b) (!(a < b), NaN counting as not less), twice_plus(i, m) (2i, plus 1 where m),
//                         plus(a, b) (I), times(i, k) (i * k, both below 2^32), children(nodes, block, c0..c3).
// The step is detail::hierarchical_step() on every lane: the same products, sums, quotients and clamps, chosen by
// masks, so the same bits. (min(q, 1 - 2^-53) is std::min(kOneMinusEpsilon, q): both return q only below the bound.)

/// The step for the lanes' nodes whose children are c0..c3; returns the chosen child's value.
ENVKIT_LANES_TARGET inline Lanes::D step(Lanes::D c0, Lanes::D c1, Lanes::D c2, Lanes::D c3, Lanes::D& ux, Lanes::D& uy,
                                         Lanes::I& i, Lanes::I& j) {
  using L = Lanes;
  const L::D bound = L::setd(kOneMinusEpsilon);
  const L::D left = L::add(c0, c2), right = L::add(c1, c3);
  const L::D tx = L::mul(ux, L::add(left, right));
  const L::M rx = L::not_less(tx, left);  // the right column
  const L::D column = L::select(rx, left, right);
  const L::D qx = L::div(L::select(rx, tx, L::sub(tx, left)), column);
  ux = L::select(rx, qx, L::min(qx, bound));
  const L::D ty = L::mul(uy, column);
  const L::D top = L::select(rx, c0, c1), bottom = L::select(rx, c2, c3);
  const L::M ry = L::not_less(ty, top);  // the bottom child
  const L::D qy = L::div(L::select(ry, ty, L::sub(ty, top)), L::select(ry, top, bottom));
  uy = L::select(ry, qy, L::min(qy, bound));
  i = L::twice_plus(i, rx);
  j = L::twice_plus(j, ry);
  return L::select(ry, top, bottom);
}

/// Index (in 16-byte blocks) of the blocks holding the children of nodes (i, j) read at level k.
ENVKIT_LANES_TARGET inline Lanes::I block_index(const HierarchicalWalk& w, int k, Lanes::I i, Lanes::I j) {
  using L = Lanes;
  return L::plus(L::seti(std::int64_t(w.offset[k] / 4)), L::plus(L::times(j, std::int64_t(w.blocks_per_row[k])), i));
}

/// pick(u[s]) into out[s] for s < n <= sampling::kSampleGroup, kWidth samples per vector.
ENVKIT_LANES_TARGET inline void descend(const HierarchicalWalk& w, const Vec2* u, TexelSample* out, std::size_t n) {
  using L = Lanes;
  constexpr std::size_t V = L::kWidth;
  static_assert(sampling::kSampleGroup % V == 0);
  const std::size_t vectors = (n + V - 1) / V;
  HierarchicalLanes lanes;
  lanes.start(u, n, vectors * V);
  alignas(64) std::int64_t next[V];
  for (int k = w.top - 1; k >= 0; --k) {
    const bool prefetch = k > 0 && k <= w.prefetch_top;  // as pick_group(): the large levels' next blocks
    for (std::size_t v = 0; v < vectors; ++v) {
      L::D x = L::loadd(lanes.ux + V * v), y = L::loadd(lanes.uy + V * v);
      L::I i = L::loadi(lanes.i + V * v), j = L::loadi(lanes.j + V * v);
      L::D c0, c1, c2, c3;
      L::children(w.nodes, block_index(w, k, i, j), c0, c1, c2, c3);
      const L::D chosen = step(c0, c1, c2, c3, x, y, i, j);
      L::stored(lanes.ux + V * v, x);
      L::stored(lanes.uy + V * v, y);
      L::storei(lanes.i + V * v, i);
      L::storei(lanes.j + V * v, j);
      if (k == 0) L::stored(lanes.leaf + V * v, chosen);
      if (prefetch) {
        L::storei(next, block_index(w, k - 1, i, j));
        for (std::int64_t b : next) __builtin_prefetch(w.nodes + 4 * b);
      }
    }
  }
  lanes.finish(w, out, n);
}
