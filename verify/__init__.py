"""verify: compile BT-FSM models to explicit transition systems and check them."""
