// Built only by the test Architecture.BackwardIncludeDoesNotBuild, which passes when this file fails to compile: it
// belongs to a target that links envkit::maps alone, and a header of ibl (a group above maps) must not be on its path.
#include <envkit/ibl/prefilter.h>
