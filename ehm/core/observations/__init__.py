"""What the rays say: the occupied and free samples along them (samples), gathered per cell
before they are learned (evidence), and the past evidence a map keeps (memory)."""
