"""The evaluation protocol's engines: the physics episodes flown in this process, over a local
process pool or on Ray. (The rest of the protocol layer still sits at the package's top:
``episode``, ``evaluate``, ``wind_protocol``, ``map_set_eval``.)"""
