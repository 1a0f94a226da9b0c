"""Finding what lies near a point: integer cells (cells), open-addressing tables of keys
(hashing), the nearest clusters (index), anchor layers, Sec. 3.4 (anchors) and the kernels
not zero at a point (supports)."""
