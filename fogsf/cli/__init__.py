"""The `fogsf` commands: `main` is the entry point; one module per sub-command, each with
`configure(parser)` and `run(args) -> int`; `arguments` holds what they share.

Heavy imports (torch, onnx) live inside `run`, so `fogsf inspect` starts fast.
"""
