// The control of backward_include.cpp: the same kind of target (linking envkit::maps alone) builds with headers of
// maps and of the group below it, so the backward probe fails for its direction, not for its setup.
#include <envkit/core/vec.h>
#include <envkit/maps/latlong.h>
