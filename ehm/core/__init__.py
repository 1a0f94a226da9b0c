"""The algorithm of Efficient Hilbert Maps (Guizilini & Ramos, IJRR 2018), in layers: a
subpackage imports only those on the lines above it (tests/test_architecture.py checks it).
Steps of Alg. 2 and Alg. 3 take the MapConfig; the primitives they call take plain values.

primitives      integer cells, hash tables, grid walks, eigen decompositions, the logistic
                link, quick-means (Alg. 1)
sensor          range scans, rigid transforms, boxes
model           clusters, kernels (Eq. 8-13), sparse features (Alg. 2, 3)
search          the nearest clusters (Sec. 3.1, 3.4), kernel supports
observations    samples along rays, evidence per cell, the memory of past evidence
clustering      the clustering step of Alg. 2, merges (Eq. 14-15)
weights         SGD (Eq. 2-3), Gaussian posteriors, forgetting, the occupancy's uncertainty
queries         ray casting, gradients and distances for planners
snapshot, state read-only views of a learned map: for grids, and for map files
timing          stage timings
"""
