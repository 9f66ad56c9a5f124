"""Mission level: several agents and the dropped sensor network as one estimate."""
