"""Files in and out: scene formats (PLY, .splat, SOG), camera files (3DGS, NeRF, COLMAP, PLY
comments), named datasets and fetching, atomic writes. Imports harness.core only."""
