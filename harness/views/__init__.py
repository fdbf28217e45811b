"""Where to look from: synthetic rigs for scenes without cameras, the placement statistics they use,
contact sheets. Imports harness.core and harness.io."""
