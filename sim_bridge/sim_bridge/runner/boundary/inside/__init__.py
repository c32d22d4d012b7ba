"""
What runs in a node's process only: the agent, the patches it makes, the node's own main().

``agent`` (the lockstep), ``channel`` (its end of the pipes), ``proxy`` (the proxy node),
``node_patches`` (what it changes in the process), ``node_main`` (the target's main()).

Started as ``python -m sim_bridge.runner.boundary.inside.agent`` in the node's sandbox; never
imported on the trusted side. Imports the wire and the runner's readers of student code
(targets, node_styles, stepping) only.
"""
