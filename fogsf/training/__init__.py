"""Training: fit a model on chamber logs (`train`), score it on a test log (`score`); the SF
part (`sf`), its structure (`structure`), the networks (`net`), the bias part (`bias`), how
sure it is on another log (`interval`), a new unit under its design's prior (`with_prior`)."""
