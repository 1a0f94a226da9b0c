"""Learning the weights: stochastic gradient descent, Eq. 2-3 (sgd), a Gaussian posterior per
weight (posterior) and the occupancy's uncertainty (uncertainty)."""
