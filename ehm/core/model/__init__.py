"""The classifier's features: the map's clusters (clusters), their kernels, Eq. 8-13
(kernels), and sparse features of many points (features)."""
