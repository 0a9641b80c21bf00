"""Export trained models to ONNX and generated fixed-size C headers."""
