"""Range scans as they come in: scans (scan), coordinate frames over time (frames), rigid
transforms (geometry) and rays clipped to boxes (boxes)."""
