"""`fogsf plan`: the chamber program that buys the most accuracy per chamber hour.

programs.py builds candidate programs from templates inside the chamber's limits;
evaluate.py simulates each on population gyros, trains the default model's lag bank on it
and scores it on test loops across the rate envelope; search.py runs that over gyros on the
executor; report.py ranks (also over the rates not in each program), writes the table, the
figure and program.csv. prior_program.py plans a new unit's short program under its
design's prior (`fogsf plan --prior`).
"""
