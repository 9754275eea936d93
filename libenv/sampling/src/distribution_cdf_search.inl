// A group of two-sided CDF searches over vectors of lanes, written once for every instruction set: included by
// distribution_cdf_avx2.cpp and distribution_cdf_avx512.cpp (no include guard), each inside its own namespace after
// defining
//   ENVKIT_LANES_TARGET   the target attribute of the functions below;
//   struct Lanes          kWidth, the types D (kWidth doubles), I (kWidth int64) and M (a mask of lanes), and
//                         loadd/stored/loadi/storei, setd/seti, sub/div (D), plus/minus/half (I, half of values >= 0),
//                         select(m, a, b) (m ? b : a, for D and I), less/at_least/not_less (D: <, >=, !(a < b) with
//                         NaN not less), greater (I), both/either/but_not(a, b) (a & b, a | b, ~a & b), any(m),
//                         first(c) (the first c lanes), gather(base, m, index) (base[index] in double, 0 outside m).
// Each lane does TwoSidedCdf::find(): the same part decision, the same probes and comparisons as libstdc++'s
// std::upper_bound / std::partition_point, and the same step and fraction arithmetic, so the same bins and bits.

/// Search k (k < n <= sampling::kSampleGroup) finds u[k] in the two-sided CDF of bins[k] bins split at split[k]
/// stored at base + start[k], as find(u[k], fraction[k], step[k]) returning bin[k].
ENVKIT_LANES_TARGET inline void search(const float* base, const std::int64_t* start, const int* bins, const int* split,
                                       const double* u, std::size_t n, int* bin, double* fraction, double* step) {
  using L = Lanes;
  constexpr std::size_t G = sampling::kSampleGroup, W = L::kWidth;
  static_assert(G % W == 0);
  alignas(64) std::int64_t from[G], sp[G], first[G], count[G], next[W];
  alignas(64) double us[G], rs[G];
  L::M forward[G / W], lanes[G / W];
  const std::size_t vectors = (n + W - 1) / W;
  // Lanes past n search an empty range from entry 0 of the first table, and are dropped at the end.
  for (std::size_t k = 0; k < vectors * W; ++k) {
    const bool real = k < n;
    from[k] = real ? start[k] : start[0];
    sp[k] = real ? split[k] : 0;
    count[k] = real ? bins[k] : 0;
    us[k] = real ? u[k] : 0.0;
  }
  for (std::size_t v = 0; v < vectors; ++v) lanes[v] = L::first(std::min(W, n - W * v));
  const L::I zero = L::seti(0), one = L::seti(1);
  const L::D half_unit = L::setd(0.5), unit = L::setd(1.0);
  // Which part holds the bin (TwoSidedCdf::forward): u < 1/2, or the remaining mass at the split is below r = 1 - u.
  // The forward part searches entries [0, split), the backward part [split, bins).
  for (std::size_t v = 0; v < vectors; ++v) {
    const L::I origin = L::loadi(from + W * v), s = L::loadi(sp + W * v);
    const L::D uv = L::loadd(us + W * v), rv = L::sub(unit, uv);
    const L::D at_split = L::gather(base, lanes[v], L::plus(origin, s));
    const L::M f = L::either(L::less(uv, half_unit), L::less(at_split, rv));
    forward[v] = f;
    L::stored(rs + W * v, rv);
    const L::I begin = L::select(f, s, zero);
    const L::I len = L::select(f, L::minus(L::loadi(count + W * v), s), s);
    L::storei(first + W * v, begin);
    L::storei(count + W * v, L::select(lanes[v], zero, len));
    L::storei(next, L::plus(origin, L::plus(begin, L::half(len))));
    for (std::int64_t p : next) __builtin_prefetch(base + p);
  }
  // One halving step of every search per round: the group's probes are in flight together, and each step
  // prefetches its search's next probe.
  for (bool more = true; more;) {
    more = false;
    for (std::size_t v = 0; v < vectors; ++v) {
      L::I f = L::loadi(first + W * v), l = L::loadi(count + W * v);
      const L::M active = L::greater(l, zero);
      if (!L::any(active)) continue;
      const L::I origin = L::loadi(from + W * v);
      const L::I half = L::half(l), middle = L::plus(f, half);
      const L::D e = L::gather(base, active, L::plus(origin, middle));
      const L::D uv = L::loadd(us + W * v), rv = L::loadd(rs + W * v);
      // TwoSidedCdf::after: forward part !(u < e), backward part e >= r.
      const L::M after = L::both(
          active, L::either(L::both(forward[v], L::not_less(uv, e)), L::but_not(forward[v], L::at_least(e, rv))));
      f = L::select(after, f, L::plus(middle, one));              // first = middle + 1
      l = L::select(after, l, L::minus(L::minus(l, half), one));  // len -= half + 1
      l = L::select(L::but_not(after, active), l, half);          // len = half
      L::storei(first + W * v, f);
      L::storei(count + W * v, l);
      L::storei(next, L::plus(origin, L::plus(f, L::half(l))));
      for (std::int64_t p : next) __builtin_prefetch(base + p);
      more |= L::any(L::greater(l, zero));
    }
  }
  // TwoSidedCdf::finish for bin i = first - 1: its step from the two stored entries (forward, backward or the
  // junction bin split - 1) and the fraction of it before u.
  for (std::size_t v = 0; v < vectors; ++v) {
    const L::I origin = L::loadi(from + W * v), s = L::loadi(sp + W * v);
    const L::I i1 = L::loadi(first + W * v), i = L::minus(i1, one);
    const L::D ti = L::gather(base, lanes[v], L::plus(origin, i));
    const L::D ti1 = L::gather(base, lanes[v], L::plus(origin, i1));
    const L::M rising = L::greater(s, i1), falling = L::but_not(L::greater(s, i), lanes[v]);  // i + 1 < s, i >= s
    L::D st = L::sub(L::sub(unit, ti1), ti);  // the junction bin: (1 - t[i + 1]) - t[i]
    st = L::select(rising, st, L::sub(ti1, ti));
    st = L::select(falling, st, L::sub(ti, ti1));
    const L::D uv = L::loadd(us + W * v), rv = L::loadd(rs + W * v);
    const L::D before = L::select(forward[v], L::sub(ti, rv), L::sub(uv, ti));  // u - t[i] or t[i] - r
    alignas(64) double fr[W], stv[W];
    alignas(64) std::int64_t iv[W];
    L::stored(fr, L::div(before, st));
    L::stored(stv, st);
    L::storei(iv, i);
    for (std::size_t l = 0; l < W && W * v + l < n; ++l) {
      bin[W * v + l] = int(iv[l]);
      fraction[W * v + l] = fr[l];
      step[W * v + l] = stv[l];
    }
  }
}
