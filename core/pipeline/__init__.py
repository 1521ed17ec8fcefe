"""From passes to results: the plan, the one call of a technique, apply, frame sequences, the
material mapping and the fitted parameters it applies, and ``auto``'s choice of a technique."""
