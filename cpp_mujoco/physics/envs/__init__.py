"""The gymnasium envs of the physics backend: ``MuJoCo-v0`` (a batch of one), its vector env and
the mixed-weather vector env, all flying
:class:`~cpp_mujoco.physics.envs.episodes.FlightEpisodes`."""
