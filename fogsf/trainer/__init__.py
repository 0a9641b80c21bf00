"""fogsf's Python side, by stage: logs/ (read, write, metrics), models/ (the streaming
artifact, features, structures), training/ (fit, score, rate transfer), gsa/ (the optimizer),
sim/ (the physics simulator), diagnose/, plan/, and commands/ (one module per sub-command)."""
