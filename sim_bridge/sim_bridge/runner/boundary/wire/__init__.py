"""The frames a node's process and the trusted side exchange over pipes: no module of the kit."""
