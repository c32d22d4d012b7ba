"""
The trusted side of the boundary: the sandbox a node process runs in, and the link to it.

The sandbox (``sandbox``, ``scratch``, ``sandbox_host``, ``sandbox_view``, ``sandbox_leftovers``,
``node_sandbox``, ``kit_answers``): an identity, limits, what the run sees and what it leaves.
The link (``link``, ``topics``, ``boundary_checks``): starts the node process, steps it, and
checks each frame and message before anything of it is published. Never imports the inside.
"""
