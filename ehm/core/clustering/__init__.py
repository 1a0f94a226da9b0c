"""How samples become the map's clusters: the clustering step of Alg. 2 (grouping; quick-means
itself is a primitive), new clusters joining the map's (merging) and orientation clustering,
Eq. 14-15 (coplanar)."""
