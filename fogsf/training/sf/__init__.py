"""The SF part of `fogsf train`: the model's features fitted to the training logs."""
