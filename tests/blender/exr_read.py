"""exr_read.py: a small reader for scanline OpenEXR files (no OpenEXR binding
exists for Debian 12's Python): NONE, ZIPS and ZIP compression, HALF and
FLOAT channels. Enough for the files gi-bake and Blender write in the tests.

read(path) -> (width, height, {channel name: list of floats, row-major})
Usage as a script: exr_read.py FILE prints the size and each channel's mean."""
import struct
import sys
import zlib

COMPRESSION_LINES = {0: 1, 2: 1, 3: 16}  # NONE, ZIPS, ZIP
PIXEL_BYTES = {1: 2, 2: 4}               # HALF, FLOAT


def _header(d):
    if d[:4] != b"\x76\x2f\x31\x01":
        raise ValueError("not an OpenEXR file")
    if struct.unpack("<I", d[4:8])[0] & 0x200:
        raise ValueError("tiled EXR files are not supported")
    pos, attrs = 8, {}
    while d[pos] != 0:
        end = d.index(b"\0", pos)
        name = d[pos:end].decode()
        tend = d.index(b"\0", end + 1)
        kind = d[end + 1:tend].decode()
        size = struct.unpack("<i", d[tend + 1:tend + 5])[0]
        attrs[name] = (kind, d[tend + 5:tend + 5 + size])
        pos = tend + 5 + size
    return attrs, pos + 1


def _channels(raw):
    out, pos = [], 0
    while raw[pos] != 0:
        end = raw.index(b"\0", pos)
        ptype = struct.unpack("<i", raw[end + 1:end + 5])[0]
        out.append((raw[pos:end].decode(), ptype))
        pos = end + 17
    return out


def _unzip(data, expected):
    buf = bytearray(zlib.decompress(data))
    for t in range(1, len(buf)):
        buf[t] = (buf[t - 1] + buf[t] - 128) & 0xFF
    half = (len(buf) + 1) // 2
    out = bytearray(len(buf))
    out[0::2] = buf[:half]
    out[1::2] = buf[half:]
    if len(out) != expected:
        raise ValueError("chunk decompresses to %d bytes, expected %d" % (len(out), expected))
    return bytes(out)


def read(path):
    d = open(path, "rb").read()
    attrs, pos = _header(d)
    chans = sorted(_channels(attrs["channels"][1]))
    comp = attrs["compression"][1][0]
    if comp not in COMPRESSION_LINES:
        raise ValueError("compression %d is not supported" % comp)
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines = COMPRESSION_LINES[comp]
    nchunks = (h + lines - 1) // lines
    offsets = struct.unpack("<%dQ" % nchunks, d[pos:pos + 8 * nchunks])
    data = {name: [0.0] * (w * h) for name, _ in chans}
    for off in offsets:
        y, size = struct.unpack("<2i", d[off:off + 8])
        row0 = y - y0
        n = min(lines, h - row0)
        expected = n * w * sum(PIXEL_BYTES[t] for _, t in chans)
        blob = d[off + 8:off + 8 + size]
        raw = blob if size == expected or comp == 0 else _unzip(blob, expected)
        p = 0
        for r in range(n):
            for name, t in chans:
                fmt = "<%d%s" % (w, "e" if t == 1 else "f")
                vals = struct.unpack(fmt, raw[p:p + w * PIXEL_BYTES[t]])
                p += w * PIXEL_BYTES[t]
                data[name][(row0 + r) * w:(row0 + r + 1) * w] = vals
    return w, h, data


if __name__ == "__main__":
    w, h, ch = read(sys.argv[1])
    print("%d x %d" % (w, h))
    for name in sorted(ch):
        print("%s mean %.6g" % (name, sum(ch[name]) / len(ch[name])))
