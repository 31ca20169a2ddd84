"""How a mirror planner's call picks its candidates and its plan: one module per strategy."""
