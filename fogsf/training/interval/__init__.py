"""How sure a model is on another log: the rate-transfer check and its interval."""
