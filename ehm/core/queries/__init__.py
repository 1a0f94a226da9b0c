"""What planners ask a learned map: where rays stop (raycast) and which way the occupancy
rises (gradient)."""
