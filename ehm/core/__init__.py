"""The algorithm of Efficient Hilbert Maps (Guizilini & Ramos, IJRR 2018), grouped by concern.
Steps of Alg. 2 and Alg. 3 take the MapConfig; the primitives they call (quick-means, kernels,
compiled loops) take plain values.

sensor          range scans, coordinate frames, rigid transforms, boxes
observations    samples along rays, evidence per cell, the memory of past evidence
clustering      quick-means (Alg. 1), the clustering step of Alg. 2, merges (Eq. 14-15)
model           clusters, kernels (Eq. 8-13), sparse features (Alg. 2, 3), the logistic link
search          cells, hashing, the nearest clusters (Sec. 3.1, 3.4), kernel supports
weights         SGD (Eq. 2-3), Gaussian posteriors, the occupancy's uncertainty
queries         ray casting and gradients for planners
snapshot, state read-only views of a learned map: for grids, and for map files
timing          stage timings
"""
