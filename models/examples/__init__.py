"""Teaching models: a two-area pick/place, the preemption spectrum and the seeded defects."""
