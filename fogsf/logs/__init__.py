"""Chamber logs as rigs write them: the log in memory (`chamber_log`), the reader (`logio`),
the columns as a validated log (`validation`), the writer (`writer`), reading a file's formats
(`read`), the column map (`mapping`) and what a log measures (`measure`: SF windows and
metrics, the bias, pairs, plateaus)."""
