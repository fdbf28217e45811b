"""Splat renderers behind one contract: ``render(scene, camera, background) -> (H, W, 3) float32``."""
