"""The air the drones fly in: steady wind, gusts, Dryden turbulence, and the drag they cause."""
