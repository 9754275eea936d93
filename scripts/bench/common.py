"""What the benchmarks and the report share: scene files, EXR reading, region masks from envrender's camera, relMSE.

Run the benchmarks as modules of the package `bench` with scripts/ on the Python path (their .sh wrappers do:
PYTHONPATH=scripts python3 -m bench.bench_cycles ...), so that they import each other and this module without
editing sys.path.

  load_scene(path)               envrender scene JSON (// and /* */ comments allowed)
  read_exr(path, channels, sub)  one part of an image as float64 H x W x C, row 0 on top (envkit or oiiotool)
  exr_attr(path, key)            one header attribute as text (oiiotool --info -v)
  rel_mse(img, ref, ...)         mean((I - R)^2 / (R^2 + 1e-2)), optionally over a mask and minus R's own variance
  camera_rays(camera, w, h, ...) envrender's pinhole camera (renderer/src/camera.cpp) through image points
  region_masks(spec, size)       per pixel the region every sub-pixel ray sees (bench_cycles' scene description)
  sphere_pixels(scene, w, h)     per sphere of a scene file the pixels lying entirely on it
"""
import json
import math
import os
import re
import subprocess
import sys

import numpy as np

try:
    import envkit  # the module built beside the tools: read_exr's in-process path
except ImportError:
    envkit = None

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# relMSE's offset: keeps dark reference pixels from dominating the mean.
EPS = 1e-2


class ReadFailed(RuntimeError):
    """An image read_exr cannot read (the file and the problem in its message)."""


def load_scene(path):
    """An envrender scene file as a dict (its comments removed)."""
    with open(path) as f:
        text = f.read()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"(^|[^:])//[^\n]*", r"\1", text)
    return json.loads(text)


def read_exr(path, channels="R,G,B", subimage=0):
    """Channels of one subimage (EXR part, by index or name) as float64 H x W x C, row 0 on top: the data window (a
    render of a --crop window holds only the window). Part 0's R,G,B come through envkit.read_image, in process, when
    the module is importable (the .sh wrappers put build/python on the path): oiiotool's two runs per image took about
    a second each. The first such read of a process is compared with oiiotool's, and a disagreement beyond the
    precision oiiotool prints sends every later read back to oiiotool (IN_PROCESS_READ says so). Other parts and
    channels come through oiiotool."""
    if channels == "R,G,B" and str(subimage) == "0" and IN_PROCESS_READ["on"]:
        img = _read_in_process(path)
        if img is not None:
            return img
    return _read_through_oiiotool(path, channels, subimage)


# Whether read_exr reads part 0's colour in process, whether that was checked against oiiotool, and why it was turned
# off (None while it is on).
IN_PROCESS_READ = {"on": envkit is not None, "checked": False, "off_because": None}


def _read_in_process(path):
    """Part 0's R,G,B through envkit, or None when that read does not serve (not an RGB(A) image, or disagreeing)."""
    try:
        img = envkit.read_image(path)
    except envkit.Error as e:
        raise ReadFailed(str(e) if path in str(e) else f"{path}: {e}") from e
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        return None
    img = img[..., :3].astype(np.float64)
    if IN_PROCESS_READ["checked"]:
        return img
    IN_PROCESS_READ["checked"] = True
    slow = _read_through_oiiotool(path)
    # oiiotool --dumpdata prints 9 decimals (5e-10 absolute), or float32's own precision for large values
    if slow.shape == img.shape and np.all(np.abs(img - slow) <= 1e-7 * np.abs(slow) + 1e-9):
        return img
    IN_PROCESS_READ.update(on=False, off_because=f"{path}: envkit.read_image disagrees with oiiotool")
    print(f"read_exr: {IN_PROCESS_READ['off_because']}; every later image is read through oiiotool", file=sys.stderr)
    return slow


def _read_through_oiiotool(path, channels="R,G,B", subimage=0):
    """read_exr through oiiotool: it extracts the channels to a float EXR and prints its pixels (--dumpdata, 9
    decimals: 5e-10 absolute, negligible against rel_mse's EPS). Not through FITS: OpenImageIO 2.4 writes FITS rows
    bottom-up shifted by one (the top row is lost)."""
    tmp = "%s.%d.read.exr" % (path, os.getpid())
    try:
        subprocess.run(["oiiotool", path, "--subimage", str(subimage), "--ch", channels, "-d", "float", "-o", tmp],
                       check=True, capture_output=True, text=True)
        text = subprocess.run(["oiiotool", "--dumpdata", tmp], check=True, capture_output=True, text=True).stdout
    except subprocess.CalledProcessError as e:
        raise ReadFailed(f"{path}: no channels {channels} in part {subimage}: {e.stderr.strip()[-200:]}") from e
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    lines = text.splitlines()
    w, h = map(int, lines[0].split(":", 1)[1].split(",")[0].split("x"))
    values = [ln.split(":", 1)[1] for ln in lines[1:] if ln.strip().startswith("Pixel (")]
    return np.array(" ".join(values).split(), dtype=np.float64).reshape(h, w, -1)


def exr_attr(path, key):
    """The header attribute `key` as text (quotes removed), or None."""
    out = subprocess.run(["oiiotool", "--info", "-v", path], check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        line = line.strip()
        if line.startswith(key + ":"):
            return line[len(key) + 1:].strip().strip('"')
    return None


def rel_mse(img, ref, mask=None, ref_variance=None):
    """mean((I - R)^2 / (R^2 + EPS)) over every channel of the pixels in `mask` (a boolean H x W array; None: all).
    With ref_variance (the reference's variance of the mean per pixel and channel, the shape of ref), that noise is
    taken off each term: the error against the converged image; floored at 1e-30 so that efficiencies stay finite."""
    img = np.asarray(img, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    sq = (img - ref) ** 2
    if ref_variance is not None:
        sq = sq - np.asarray(ref_variance, dtype=np.float64)
    e = sq / (ref ** 2 + EPS)
    value = float(e[mask].mean() if mask is not None else e.mean())
    return max(value, 1e-30) if ref_variance is not None else value


def camera_rays(camera, width, height, px, py):
    """envrender's pinhole camera (renderer/src/camera.cpp; `camera` as in a scene file) through image points (px, py)
    in pixels, row 0 on top (arrays, broadcast together). Returns the origin and unit directions (..., 3)."""
    pos = np.array(camera["position"], float)
    fwd = np.array(camera["look_at"], float) - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.array(camera.get("up", [0, 1, 0]), float))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    t = math.tan(0.5 * math.radians(camera.get("fov", 40)))
    sx = (2 * np.asarray(px, float) / width - 1) * t * (width / height)
    sy = (1 - 2 * np.asarray(py, float) / height) * t
    sx, sy = np.broadcast_arrays(sx, sy)
    d = fwd + right * sx[..., None] + up * sy[..., None]
    return pos, d / np.linalg.norm(d, axis=-1, keepdims=True)


def sphere_distance(origin, d, centre, radius):
    """Distance along unit directions d from origin to the near side of a sphere; inf where the ray misses it or the
    sphere is behind."""
    oc = origin - np.array(centre, float)
    b = (d * oc).sum(-1)
    disc = b * b - ((oc * oc).sum() - radius ** 2)
    t = -b - np.sqrt(np.maximum(disc, 0))
    return np.where((disc > 0) & (t > 0), t, np.inf)


def region_masks(spec, size, sub=4):
    """Label per pixel (index into spec["regions"], -1 background, -2 mixed) for bench_cycles' scene description
    (spheres, meshes, a ground square): every one of sub x sub sub-pixel rays must see the same object."""
    w, h = size
    offs = (np.arange(sub) + 0.5) / sub
    px = (np.arange(w)[None, :, None, None] + offs[None, None, None, :])
    py = (np.arange(h)[:, None, None, None] + offs[None, None, :, None])
    pos, d = camera_rays(spec["camera"], w, h, px, py)
    best = np.full(d.shape[:-1], np.inf)
    label = np.full(d.shape[:-1], -1)
    regions = spec["regions"]
    for sp in spec["spheres"]:
        tt = sphere_distance(pos, d, sp["center"], sp["radius"])
        hit = tt < best
        best[hit] = tt[hit]
        label[hit] = regions.index(sp["material"])
    for m in spec.get("meshes", []):
        tri = m["triangles"]  # (n, 3, 3)
        # Rays that can hit the mesh: those through its bounding sphere (Moeller-Trumbore on those only).
        centre = tri.reshape(-1, 3).mean(0)
        radius = np.linalg.norm(tri.reshape(-1, 3) - centre, axis=1).max()
        oc = pos - centre
        b = (d * oc).sum(-1)
        near = b * b - ((oc * oc).sum() - radius ** 2) > 0
        dn = d[near]
        tbest = best[near]
        lab = label[near]
        for v0, v1, v2 in tri:
            e1, e2 = v1 - v0, v2 - v0
            pv = np.cross(dn, e2)
            det = pv @ e1
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / det
                tv = pos - v0
                u = (pv @ tv) * inv
                qv = np.cross(tv, e1)
                v = (dn @ qv) * inv
                tt = (qv @ e2) * inv
            hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (tt > 1e-9) & (tt < tbest)
            tbest[hit] = tt[hit]
            lab[hit] = regions.index(m["material"])
        best[near] = tbest
        label[near] = lab
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = -pos[1] / d[..., 1]
    hp = pos + d * tg[..., None]
    s = spec["ground"]["half_size"]
    hit = (tg > 0) & (tg < best) & (np.abs(hp[..., 0]) < s) & (np.abs(hp[..., 2]) < s)
    label[hit] = regions.index("ground")
    flat = label.reshape(h, w, sub * sub)
    out = flat[..., 0].copy()
    out[(flat != flat[..., :1]).any(-1)] = -2
    return out


def sphere_pixels(scene, width, height):
    """Per sphere of an envrender scene file (keyed by its material), the pixels (x, y) lying entirely on it, in row
    order: the rays through the pixel's centre and its four corners all hit the sphere (other objects ignored)."""
    corners = np.array([(0.5, 0.5), (0, 0), (1, 0), (0, 1), (1, 1)])
    px = np.arange(width)[None, :, None] + corners[None, None, :, 0]
    py = np.arange(height)[:, None, None] + corners[None, None, :, 1]
    pos, d = camera_rays(scene["camera"], width, height, px, py)
    pixels = {}
    for s in scene["shapes"]:
        if s["type"] != "sphere":
            continue
        inside = np.isfinite(sphere_distance(pos, d, s["center"], s["radius"])).all(-1)
        ys, xs = np.nonzero(inside)
        if len(xs):
            pixels[s["material"]] = [(int(x), int(y)) for x, y in zip(xs, ys)]
    return pixels
