"""The algorithm of Efficient Hilbert Maps (Guizilini & Ramos, IJRR 2018), one module per
part of the paper. Steps of Alg. 2 and Alg. 3 take the MapConfig; the primitives they call
(quick-means, kernels, compiled loops) take plain values.

scan, samples       range scans and the occupied / free samples drawn along their rays
quickmeans          Alg. 1;  grouping: the clustering step of Alg. 2 built on it
kernels             k_SP with localized length-scales (Eq. 8, 10-12), planar kernel (Eq. 13)
clusters, merging   the map's clusters and how new ones join them (Alg. 2 lines 4-21)
coplanar            orientation clustering (Eq. 14-15)
anchors, index      the search for a point's nearest clusters (Sec. 3.1, 3.4)
features            sparse features, one neighbour search per group of points (Alg. 2, 3)
sgd, logistic       the classifier: training (Eq. 2-3) and its link (Eq. 1)
snapshot, state     read-only views of a learned map: for grids, and for map files
cells, geometry, timing   integer cells, rigid transforms, stage timings
"""
