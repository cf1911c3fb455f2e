"""The controller: the reference a macro-action follows, the geometric SE(3) law, the mixer and
the disturbance observer; their per-drone state and the compiled tick that runs them."""
