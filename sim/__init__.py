"""sim: simulated cells described by scene files (the ARIAC kitting cell among them) that run checked models."""
