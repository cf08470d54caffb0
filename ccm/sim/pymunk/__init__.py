"""The planar pymunk (Chipmunk2D) backend: simulator, scene, seed B's HRI elements."""
