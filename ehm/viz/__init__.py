"""Pictures of maps, off-screen: colours, a mesh rasterizer and PNG figures."""
