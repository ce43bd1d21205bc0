"""models: the paper's ARIAC model, a port of the authors' original, and examples."""
