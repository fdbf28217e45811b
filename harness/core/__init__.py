"""The vocabulary every layer shares: the scene and camera models, errors, paths, typed
parameters, the registry pattern, ratios, stage timers. Imports nothing else of the project."""
