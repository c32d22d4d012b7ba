"""
The trust boundary: a node file's process, the trusted side's end of it, and the wire between.

Three parts, each a sub-package, with the contract ``.importlinter`` checks:

- ``inside``: what runs in a node's process only (``python -m
  sim_bridge.runner.boundary.inside.agent``): the agent, its patches, the node's own main(). It
  imports the wire and, of the runner, only what reads student code (targets, node_styles,
  stepping); nothing of the kit imports it.
- ``outside``: what runs on the trusted side: the sandbox a node process runs in, what it may
  see and what it leaves behind, and the link that starts the process, steps it and checks every
  frame before anything of it is published. It never imports the inside.
- ``wire``: the frames both sides exchange over pipes. It imports nothing of the kit.
"""
