"""The evaluation protocol: the one episode loop, the policy protocol, ``evaluate`` over the
paper's episodes (grid or physics, local or Ray), wind and map-set protocols, the optimum beside
every result. It knows a policy only through :mod:`~cpp_mujoco.protocol.policy`."""
