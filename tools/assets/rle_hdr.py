#!/usr/bin/env python3
"""Re-encode flat (uncompressed) Radiance .hdr files with the format's run-length encoding.

The pixels stay the same, byte for byte: each scanline's RGBE bytes are split into four
channel planes and each plane is stored as runs (a count above 128 repeats the next byte
count-128 times) and literals (a count up to 128 is followed by that many bytes), as
Radiance's own `fwritecolrs` does. The script decodes its output again and checks it.

    python3 tools/assets/rle_hdr.py IN.hdr OUT.hdr
"""
import sys


def read_header(data):
    """(header lines, width, height, offset of the pixels) of a Radiance file."""
    end = data.index(b"\n\n") + 2
    line_end = data.index(b"\n", end)
    size = data[end:line_end].split()
    if size[0] != b"-Y" or size[2] != b"+X":
        raise SystemExit(f"unsupported orientation {size!r}")
    return data[:end], data[end : line_end + 1], int(size[3]), int(size[1]), line_end + 1


def encode_plane(plane):
    out = bytearray()
    i, n = 0, len(plane)
    while i < n:
        run = 1
        while i + run < n and run < 127 and plane[i + run] == plane[i]:
            run += 1
        if run >= 3:
            out += bytes([128 + run, plane[i]])
            i += run
            continue
        # Literals up to the next run of three or more.
        j = i
        while j < n and j - i < 128:
            if j + 2 < n and plane[j] == plane[j + 1] == plane[j + 2]:
                break
            j += 1
        out.append(j - i)
        out += plane[i:j]
        i = j
    return out


def decode_scanline(data, pos, width):
    assert data[pos] == 2 and data[pos + 1] == 2
    assert (data[pos + 2] << 8) | data[pos + 3] == width
    pos += 4
    planes = []
    for _ in range(4):
        plane = bytearray()
        while len(plane) < width:
            count = data[pos]
            pos += 1
            if count > 128:
                plane += bytes([data[pos]]) * (count - 128)
                pos += 1
            else:
                plane += data[pos : pos + count]
                pos += count
        assert len(plane) == width
        planes.append(plane)
    return bytes(b for px in zip(*planes) for b in px), pos


def main(src, dst):
    data = open(src, "rb").read()
    header, size_line, width, height, start = read_header(data)
    pixels = data[start:]
    if len(pixels) != width * height * 4 or not 8 <= width < 32768:
        raise SystemExit(f"{src}: not a flat {width}x{height} file")
    out = bytearray(header + size_line)
    for y in range(height):
        row = pixels[y * width * 4 : (y + 1) * width * 4]
        out += bytes([2, 2, width >> 8, width & 255])
        for c in range(4):
            out += encode_plane(row[c::4])
    pos = len(header) + len(size_line)
    for y in range(height):
        row, pos = decode_scanline(out, pos, width)
        assert row == pixels[y * width * 4 : (y + 1) * width * 4], f"scanline {y} differs"
    open(dst, "wb").write(out)
    print(f"{src}: {len(data)} -> {len(out)} bytes, pixels unchanged")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
