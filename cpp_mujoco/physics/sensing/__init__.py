"""The coverage sensor: the downward camera's footprint on the ground decides what is seen."""
