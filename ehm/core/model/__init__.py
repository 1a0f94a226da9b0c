"""The classifier's features: the map's clusters (clusters), their kernels, Eq. 8-13 (kernels),
covariances decomposed (eigen), sparse features of many points (features) and the logistic
link, Eq. 1 (logistic)."""
