"""File formats, one module per format: scans in (readers and one module per scan format),
maps, grids and meshes out and back."""
