"""How the physics scene is seen: offscreen GL and videos, the chase and onboard cameras, and
what they draw beside the model (scenery, trail, the enlarged airframe) — render time only."""
