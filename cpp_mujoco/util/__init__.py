"""The bottom layer: atomic files, signals, bundled data, text tables — nothing of the MDP."""
