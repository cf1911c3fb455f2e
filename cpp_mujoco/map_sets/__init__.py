"""Maps made by rule: the generator, the size classes' budgets and the named held-out sets."""
