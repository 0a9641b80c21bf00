"""The plateau model (docs/train.md, "Plateau tables"): the SF as a function of rate and
temperature fitted on plateau tables (its forms and their choice:
`models.structures.rate_forms`, `rate_choice`), and `fogsf train` on the tables."""
