"""Finding the kernels near a point: the nearest clusters (index), anchor layers, Sec. 3.4
(anchors), counts of cluster centres per cell (centre_counts) and the kernels not zero at a
point (supports)."""
