"""How samples become clusters: quick-means, Alg. 1 (quickmeans), the clustering step of
Alg. 2 (grouping), new clusters joining the map's (merging) and orientation clustering,
Eq. 14-15 (coplanar)."""
