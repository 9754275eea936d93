"""envkit.batch's memory bound: the peak resident memory of a worker processing one map, predicted from the map's
header before it is read, and the parsing of memory sizes (--memory-limit 6GB).

The bound (docs/PYTHON.md; measured by scripts/bench/bench_batch.py) is linear in texels. The map is loaded once
(float RGB) and each step's result is released when written, so the steps do not add up: the largest one counts.

    peak bytes <= BASE_BYTES + 4 C T + max(convert, bake, prefilter)
    convert   = (4 C + 1) * output texels (--to and --size; with --size 0 as many as the input's T)
    bake      = (TABLE_BYTES * table kinds + 4 C when the grid is resampled) * grid texels
    prefilter = (4 C + 2) * T

where T is the input's texels and C its channels (3 for RGB, 4 with alpha), both from its header (width x height,
summed over the parts of a multi-part EXR). With the defaults (latlong at the input's density, hierarchical tables
on the input's grid) and an RGB map that is BASE_BYTES + 29 T.
"""

import re
import struct

# A dask worker process before any map (Python, dask, envkit and its libraries) and the allocator's slack.
BASE_BYTES = 192 << 20
# Bytes of a float channel: the loaded map and a converted one hold 4 C bytes per texel.
CHANNEL_BYTES = 4
# One kind of sampling table (cdf, alias, hierarchical, ...) with its builder's scratch, per grid texel.
TABLE_BYTES = 17

# Texels of an output parameterization at --size N (envconvert's footer: latlong 2N x N, healpix 4N x 3N, ...).
_TEXELS_PER_N2 = {"latlong": 2, "cube": 6, "paraboloid": 2, "healpix": 12, "skylatlong": 4}


def output_texels(to, size, input_texels):
    """Texels of the map converted to `to` at --size `size` (0: the input's density, counted as the input's
    texels)."""
    if not size:
        return input_texels
    return _TEXELS_PER_N2.get(to, 1) * size * size


def predicted_peak(input_texels, channels, options):
    """Bytes a worker's resident memory reaches at most while processing a map of `input_texels` texels and
    `channels` channels with the batch `options` (envkit.batch.default_options)."""
    texel = CHANNEL_BYTES * channels
    steps = [0]
    if options["convert"]:
        steps.append((texel + 1) * output_texels(options["to"], options["size"], input_texels))
    if options["bake"]:
        grid = output_texels(options["bake_grid"], options["bake_size"], input_texels)
        resampled = options["bake_grid"] != "latlong" or options["bake_size"] != 0
        steps.append((TABLE_BYTES * max(1, len(options["tables"])) + (texel if resampled else 0)) * grid)
    if options["prefilter"]:
        steps.append((texel + 2) * input_texels)
    return BASE_BYTES + texel * input_texels + max(steps)


def default_limit(predictions, workers):
    """The default memory limit per worker: the largest prediction (None: unknown, ignored) with a quarter more,
    at most the machine's memory (dask's view of it: cgroup limits included) shared by `workers`."""
    from distributed.system import MEMORY_LIMIT

    largest = max((p for p in predictions if p), default=BASE_BYTES)
    return min(largest + largest // 4, MEMORY_LIMIT // workers)


_UNITS = {"": 1, "B": 1, "K": 1 << 10, "KB": 1 << 10, "KIB": 1 << 10, "M": 1 << 20, "MB": 1 << 20, "MIB": 1 << 20,
          "G": 1 << 30, "GB": 1 << 30, "GIB": 1 << 30, "T": 1 << 40, "TB": 1 << 40, "TIB": 1 << 40}


def parse_bytes(text):
    """'6GB', '6G', '6GiB', '512MB', '1.5GB' or a plain byte count -> bytes (binary units: 1 GB = 2^30 bytes).
    ValueError with the accepted forms otherwise."""
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]*)?)\s*([A-Za-z]*)\s*", text)
    if not m or m.group(2).upper() not in _UNITS:
        raise ValueError("'%s' is not a size (e.g. 6GB, 512MB)" % text)
    value = int(float(m.group(1)) * _UNITS[m.group(2).upper()])
    if value <= 0:
        raise ValueError("'%s' is not a positive size" % text)
    return value


def format_bytes(n):
    """Bytes as GB (2^30) with 2 decimals, or MB below 1 GB."""
    return "%.2f GB" % (n / (1 << 30)) if n >= 1 << 30 else "%.0f MB" % (n / (1 << 20))


def header(path):
    """(texels, channels) of the image file at `path` from its header (OpenEXR, Radiance .hdr, PFM, PNG, JPEG,
    TIFF), or None when the header is not one of these or cannot be read (the worker's reader then reports the
    problem)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return None
    for reader in (_exr, _hdr, _pfm, _png, _jpeg, _tiff):
        try:
            found = reader(head)
        except (struct.error, ValueError, IndexError):
            found = None
        if found and found[0] > 0:
            return found
    return None


def _exr(head):
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    multipart = struct.unpack_from("<I", head, 4)[0] & 0x1000
    pos, total, channels = 8, 0, 0
    while True:
        window, count, pos = _exr_header(head, pos)
        if window is None:
            return None
        x0, y0, x1, y1 = window
        total += max(0, x1 - x0 + 1) * max(0, y1 - y0 + 1)
        channels = max(channels, count)
        if not multipart or head[pos] == 0:
            return total, channels


def _exr_header(head, pos):
    """(dataWindow, channel count, position after the header's terminating zero) of the header at pos."""
    window, channels = None, 0
    while head[pos] != 0:
        name_end = head.index(b"\0", pos)
        type_end = head.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", head, type_end + 1)[0]
        value = type_end + 5
        name = head[pos:name_end]
        if name == b"dataWindow":
            window = struct.unpack_from("<4i", head, value)
        elif name == b"channels":
            channels = _exr_channel_count(head[value:value + size])
        pos = value + size
        if pos >= len(head):
            return None, 0, pos
    return window, channels, pos + 1


def _exr_channel_count(chlist):
    # Entries: name, 0, then 16 bytes (pixel type, linear, reserved, x and y sampling); a 0 ends the list.
    count, pos = 0, 0
    while pos < len(chlist) and chlist[pos] != 0:
        pos = chlist.index(b"\0", pos) + 17
        count += 1
    return count


def _hdr(head):
    if not head.startswith(b"#?"):
        return None
    m = re.search(rb"\n\n([-+][YX]) +([0-9]+) +([-+][YX]) +([0-9]+)", head)
    return (int(m.group(2)) * int(m.group(4)), 3) if m else None


def _pfm(head):
    m = re.match(rb"P([Ff])\s+([0-9]+)\s+([0-9]+)\s", head)
    return (int(m.group(2)) * int(m.group(3)), 3 if m.group(1) == b"F" else 1) if m else None


def _png(head):
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    w, h, _, colour = struct.unpack_from(">IIBB", head, 16)
    return w * h, {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}.get(colour, 4)


def _jpeg(head):
    if head[:2] != b"\xff\xd8":
        return None
    pos = 2
    while pos + 9 < len(head):
        if head[pos] != 0xFF:
            return None
        marker = head[pos + 1]
        length = struct.unpack_from(">H", head, pos + 2)[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w, components = struct.unpack_from(">HHB", head, pos + 5)
            return w * h, components
        pos += 2 + length
    return None


def _tiff(head):
    order = {b"II": "<", b"MM": ">"}.get(head[:2])
    if order is None or struct.unpack_from(order + "H", head, 2)[0] != 42:
        return None
    ifd = struct.unpack_from(order + "I", head, 4)[0]
    tags = {277: 1}  # samples per pixel, 1 when absent
    for k in range(struct.unpack_from(order + "H", head, ifd)[0]):
        tag, kind = struct.unpack_from(order + "HH", head, ifd + 2 + 12 * k)
        if tag in (256, 257, 277):
            fmt = "H" if kind == 3 else "I"
            tags[tag] = struct.unpack_from(order + fmt, head, ifd + 2 + 12 * k + 8)[0]
    return (tags[256] * tags[257], tags[277]) if 256 in tags and 257 in tags else None
