"""scan_pkg: the laser lab nodes and their pure scan geometry and behaviour cores."""
