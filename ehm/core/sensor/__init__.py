"""Range scans as they come in: scans (scan), rigid transforms (geometry) and rays clipped to
boxes (boxes)."""
