"""sim: the pymunk ARIAC kitting cell that runs checked models."""
