#!/usr/bin/env python3
"""Writes bumps.png: a 256x256 tangent-space normal map (OpenGL convention, +Y up) of a
hammered surface: overlapping round dents at several scales plus fine ridges, tiling
seamlessly. Standard library only (zlib PNG writer)."""
import math, random, struct, zlib

SIZE = 256
random.seed(7)
height = [[0.0] * SIZE for _ in range(SIZE)]
for scale, count, depth in [(28, 60, 1.0), (12, 260, 0.45), (5, 900, 0.18)]:
    for _ in range(count):
        cx, cy = random.uniform(0, SIZE), random.uniform(0, SIZE)
        r = scale * random.uniform(0.7, 1.3)
        for dy in range(-int(r) - 1, int(r) + 2):
            for dx in range(-int(r) - 1, int(r) + 2):
                d2 = (dx * dx + dy * dy) / (r * r)
                if d2 < 1.0:
                    x, y = int(cx + dx) % SIZE, int(cy + dy) % SIZE
                    height[y][x] -= depth * r * 0.25 * (1.0 - d2) ** 2
for y in range(SIZE):
    for x in range(SIZE):
        height[y][x] += 0.6 * math.sin(2 * math.pi * 16 * (x + 0.3 * y) / SIZE)

rows = []
for y in range(SIZE):
    row = bytearray([0])
    for x in range(SIZE):
        gx = (height[y][(x + 1) % SIZE] - height[y][(x - 1) % SIZE]) * 0.5
        # Rows run down the image (v down); +Y of the map is up the image.
        gy = (height[(y - 1) % SIZE][x] - height[(y + 1) % SIZE][x]) * 0.5
        nx, ny, nz = -gx, -gy, 1.0
        inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
        row += bytes(max(0, min(255, round((c * inv * 0.5 + 0.5) * 255))) for c in (nx, ny, nz))
    rows.append(bytes(row))

def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", SIZE, SIZE, 8, 2, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(b"".join(rows), 9)) + chunk(b"IEND", b"")
open(__file__.rsplit("/", 1)[0] + "/bumps.png", "wb").write(png)
