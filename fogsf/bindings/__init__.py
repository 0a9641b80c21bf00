"""cffi loading of the compiled C kernel and the per-sample replay."""
