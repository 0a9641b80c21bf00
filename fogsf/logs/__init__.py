"""Chamber logs as rigs write them (the reader and writer) and the SF-error metrics."""
