"""One module per `fogsf` sub-command: each has `configure(parser)` and `run(args) -> int`.

Heavy imports (torch, onnx) live inside `run`, so `fogsf inspect` starts fast.
"""
