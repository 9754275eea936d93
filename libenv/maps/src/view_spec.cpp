#include <envkit/core/error.h>
#include <envkit/maps/view_spec.h>

#include <algorithm>
#include <cmath>

namespace envkit {

double default_fov_degrees(Kind kind) { return kind == Kind::Fisheye ? 180.0 : 90.0; }

ParamSpec view_spec(Kind kind, int width, double aspect, const ViewParams& view, const Convention& conv) {
  if (kind != Kind::Perspective && kind != Kind::Fisheye)
    throw Error(std::string(kind_name(kind)) + " is not a camera view (perspective or fisheye)");
  if (!(aspect > 0.0) || !std::isfinite(aspect)) throw Error("view aspect must be a positive number");
  ParamSpec spec = spec_for(kind, width, conv);
  spec.view = view;
  spec.height = std::max(1, static_cast<int>(std::lround(spec.width / aspect)));
  return spec;
}

void check_view(Kind kind, const ViewParams& view) {
  ParamSpec s;
  s.kind = kind;
  s.width = s.height = 8;  // the smallest image is enough: only the view's arguments are checked
  s.view = view;
  make_parameterization(s);
}

}  // namespace envkit
