"""Cube faces as py360convert hands them out: cube_format 'list' (six N x N x C arrays in the order F R B L U D)
and 'dict' (the same under the keys 'F', 'R', 'B', 'L', 'U', 'D').

py360convert's frame has +y up and its equirectangular image's centre looking along +z with +x to the right of
it; envkit's lat-long shows +X to the left of its centre (latlong.h), so a direction (x, y, z) of py360convert is
(-x, y, z) in envkit's world for the same equirectangular image. Each face texel is matched to the envkit cube
texel seeing the same direction through EnvMap.texel_of: the texels coincide, so faces are copied exactly.
"""

import numpy as np

FACE_NAMES = ("F", "R", "B", "L", "U", "D")


def _face_directions(n):
    """(6, N, N, 3) envkit world directions of the texel centres of py360convert's faces F R B L U D."""
    t = (np.arange(n) + 0.5) / n - 0.5  # texel centres across a face of the cube [-0.5, 0.5]^3
    col, row = np.meshgrid(t, t)  # col grows to the right, row downwards
    half = np.full_like(col, 0.5)
    # py360convert's xyzcube, face by face: (x, y, z) of texel (row, col).
    faces = [
        (col, -row, half),  # F: z = +0.5
        (half, -row, -col),  # R: x = +0.5
        (-col, -row, -half),  # B: z = -0.5
        (-half, -row, col),  # L: x = -0.5
        (col, half, row),  # U: y = +0.5
        (col, -half, -row),  # D: y = -0.5
    ]
    d = np.stack([np.stack(f, -1) for f in faces])
    d[..., 0] *= -1.0  # py360convert's x is envkit's -X
    return d


def _cube_texels(cube, n):
    """(6, N, N) row and column indices of the cube texels seeing the faces' texel centres."""
    pos = cube.texel_of(_face_directions(n))
    return np.floor(pos[..., 1]).astype(np.intp), np.floor(pos[..., 0]).astype(np.intp)


def _face_size(cube):
    if cube.parameterization != "cube":
        raise ValueError("faces: applies to cube maps, not %s (convert('cube') first)" % cube.parameterization)
    short = min(cube.width, cube.height)  # strips: N x 6N; crosses: 3N x 4N
    return short if cube.layout in ("vstrip", "hstrip") else short // 3


def faces(self, format="list"):
    """The six faces as py360convert's cube_format 'list' (F R B L U D, each N x N x C float32) or 'dict'
    (keys 'F', 'R', 'B', 'L', 'U', 'D'), copied from this cube map texel for texel."""
    if format not in ("list", "dict"):
        raise ValueError("format: '%s' is not 'list' or 'dict'" % (format,))
    n = _face_size(self)
    rows, cols = _cube_texels(self, n)
    out = [np.ascontiguousarray(self.data[rows[k], cols[k]]) for k in range(6)]
    return dict(zip(FACE_NAMES, out)) if format == "dict" else out


def from_faces(faces, convention=None, layout=None):
    """A cube map (envkit vertical strip, or `layout`) from py360convert's faces: a list F R B L U D or a dict with
    keys 'F', 'R', 'B', 'L', 'U', 'D' of N x N (x C) arrays."""
    from . import EnvMap

    if isinstance(faces, dict):
        missing = [k for k in FACE_NAMES if k not in faces]
        if missing:
            raise ValueError("faces: the dict lacks %s" % ", ".join(missing))
        faces = [faces[k] for k in FACE_NAMES]
    elif not isinstance(faces, (list, tuple)):
        raise TypeError("faces: expected a list of six arrays (F R B L U D) or a dict, got %s" % type(faces).__name__)
    if len(faces) != 6:
        raise ValueError("faces: expected six faces (F R B L U D), got %d" % len(faces))
    arrays = [np.asarray(f) for f in faces]
    arrays = [a[..., None] if a.ndim == 2 else a for a in arrays]
    shape = arrays[0].shape
    if len(shape) != 3 or shape[0] != shape[1] or any(a.shape != shape for a in arrays):
        raise ValueError("faces: expected six N x N (x C) arrays of one shape, got %s" % [a.shape for a in arrays])
    n, c = shape[0], shape[2]
    cube = EnvMap.blank(n, "cube", channels=c, convention=convention, layout=layout)
    rows, cols = _cube_texels(cube, n)
    data = cube.data
    for k in range(6):
        data[rows[k], cols[k]] = arrays[k]
    return cube
