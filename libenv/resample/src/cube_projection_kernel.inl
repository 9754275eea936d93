// The lane kernel of project_latlong_row_to_cube (cube_projection.h), for a lane type L (cube_projection_avx2.cpp,
// cube_projection_avx512.cpp). Every expression is CubeMap::to_image's (and apply()'s and TexelDirections'), in its
// order: the result is the same double, bit for bit. L::select(m, no, yes) is yes where m holds. ENVKIT_LANES_TARGET
// marks the functions for the including file's instruction set.
namespace envkit::detail {

template <class L>
ENVKIT_LANES_TARGET inline typename L::D clamp_lanes(typename L::D v, typename L::D lo, typename L::D hi) {
  // std::clamp: v < lo ? lo : (hi < v ? hi : v)
  return L::select(L::less(v, lo), L::select(L::less(hi, v), v, hi), lo);
}

template <class L>
ENVKIT_LANES_TARGET inline typename L::D dot_lanes(typename L::D x, typename L::D y, typename L::D z, typename L::D vx,
                                                   typename L::D vy, typename L::D vz) {
  return L::add(L::add(L::mul(x, vx), L::mul(y, vy)), L::mul(z, vz));
}

template <class L>
ENVKIT_LANES_TARGET int project_row_lanes(const CubeProjectionTables& t, const double* sin_lon, const double* cos_lon,
                                          double sin_lat, double cos_lat, int n, double* x, double* y) {
  using D = typename L::D;
  constexpr int kWidth = L::kWidth;
  const int done = n - n % kWidth;
  const D slat = L::setd(sin_lat), clat = L::setd(cos_lat), zero = L::setd(0.0), one = L::setd(1.0);
  const D half = L::setd(0.5), minus_one = L::setd(-1.0), scale = L::setd(t.scale), offset = L::setd(t.offset);
  D r[3][3];
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) r[a][b] = L::setd(t.rotation[a][b]);
  for (int i = 0; i < done; i += kWidth) {
    D dx = L::mul(L::loadu(sin_lon + i), clat), dy = slat, dz = L::mul(L::loadu(cos_lon + i), clat);
    if (t.rotate) {
      const D rx = dot_lanes<L>(dx, dy, dz, r[0][0], r[0][1], r[0][2]);
      const D ry = dot_lanes<L>(dx, dy, dz, r[1][0], r[1][1], r[1][2]);
      const D rz = dot_lanes<L>(dx, dy, dz, r[2][0], r[2][1], r[2][2]);
      dx = rx;
      dy = ry;
      dz = rz;
    }
    // The major axis picks the face; ties go to the first face in order.
    const D ax = L::abs(dx), ay = L::abs(dy), az = L::abs(dz);
    const auto on_x = L::both(L::at_least(ax, ay), L::at_least(ax, az)), on_y = L::at_least(ay, az);
    const D face_x = L::select(L::at_least(dx, zero), L::setd(1.0), L::setd(0.0));
    const D face_y = L::select(L::at_least(dy, zero), L::setd(3.0), L::setd(2.0));
    const D face_z = L::select(L::at_least(dz, zero), L::setd(5.0), L::setd(4.0));
    const auto f = L::index(L::select(on_x, L::select(on_y, face_z, face_y), face_x));
    const D major = dot_lanes<L>(dx, dy, dz, L::lookup(t.axis[0], f), L::lookup(t.axis[1], f), L::lookup(t.axis[2], f));
    const D inverse_major = L::div(one, major);
    const D a = clamp_lanes<L>(
        L::mul(dot_lanes<L>(dx, dy, dz, L::lookup(t.right[0], f), L::lookup(t.right[1], f), L::lookup(t.right[2], f)),
               inverse_major),
        minus_one, one);
    const D b = clamp_lanes<L>(
        L::mul(dot_lanes<L>(dx, dy, dz, L::lookup(t.down[0], f), L::lookup(t.down[1], f), L::lookup(t.down[2], f)),
               inverse_major),
        minus_one, one);
    // CubeMap::local_coord: (a + 1) * 0.5 * scale, plus 0.5 on corner grids.
    D la = L::mul(L::mul(L::add(a, one), half), scale), lb = L::mul(L::mul(L::add(b, one), half), scale);
    if (t.corner) {
      la = L::add(la, offset);
      lb = L::add(lb, offset);
    }
    const D x0 = L::lookup(t.origin_x, f), y0 = L::lookup(t.origin_y, f);
    const D px = clamp_lanes<L>(L::add(x0, la), x0, L::lookup(t.max_x, f));
    const D py = clamp_lanes<L>(L::add(y0, lb), y0, L::lookup(t.max_y, f));
    // A zero vector (no major component) looks at the face's centre.
    const auto valid = L::greater(major, zero);
    L::storeu(x + i, L::select(valid, L::lookup(t.centre_x, f), px));
    L::storeu(y + i, L::select(valid, L::lookup(t.centre_y, f), py));
  }
  return done;
}

}  // namespace envkit::detail
