"""Processing algorithms: each translates parameters into one core call and its results into outputs."""
