"""The bottom of the core, knowing nothing of maps: integer cells of points (cells),
open-addressing tables of keys (hashing), the cells a segment crosses (grid_walk), small
symmetric eigen decompositions (eigen), the logistic link, Eq. 1 (logistic) and quick-means,
Alg. 1 (quickmeans)."""
