"""The networks of a model: their hyper-parameters, training loops, the GSA search."""
