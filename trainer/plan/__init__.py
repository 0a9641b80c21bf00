"""`fogsf plan`: the chamber program that buys the most accuracy per chamber hour.

programs.py builds candidate programs from templates inside the chamber's limits;
evaluate.py simulates each on population gyros, trains the default model's lag bank on it
and scores it at envelope rates the program does not contain; report.py ranks, writes the
table, the figure and program.csv.
"""
