#!/usr/bin/env python3
"""Contact sheet of images for docs/results: one row per comma-separated list of files.

usage: contact_sheet.py OUT.png SCALE ROW [ROW ...]
       ROW = a.png,b.png,...   (each image is resized to 84x56, then enlarged SCALE times
                                with nearest-neighbour so pixels stay visible)

Needs Pillow (`pip install pillow`). docs/RESULTS.md names the rows of each figure.
"""
import sys

from PIL import Image

TILE_W, TILE_H = 84, 56  # the shipped model's image size
GAP = 4


def main(out, scale, rows):
    tiles = [[Image.open(p).convert("RGB").resize((TILE_W, TILE_H), Image.BILINEAR) for p in r]
             for r in rows]
    cols = max(len(r) for r in tiles)
    cell_w, cell_h = TILE_W * scale + GAP, TILE_H * scale + GAP
    sheet = Image.new("RGB", (cols * cell_w, len(tiles) * cell_h), (255, 255, 255))
    for i, row in enumerate(tiles):
        for j, tile in enumerate(row):
            big = tile.resize((TILE_W * scale, TILE_H * scale), Image.NEAREST)
            sheet.paste(big, (j * cell_w, i * cell_h))
    sheet.save(out)


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]), [r.split(",") for r in sys.argv[3:]])
