"""Walden's rule as a user's model file: heats of fusion.

``Hfus = a Tm``: the entropy of fusion of an organic crystal at its melting point is about
``a = 56.5`` J/(mol K) (P. Walden, Z. Elektrochem. 14 (1908) 713; S. H. Yalkowsky, Ind. Eng.
Chem. Fundam. 18 (1979) 108, whose form adds a term growing with the molecule's flexibility,
which the rule lacks, and one for its symmetry). One parameter; Tm in kelvin, ``predict``
returns kJ/mol. No ``jacobian``: finite differences.
"""

PARAMETERS = {"a": 56.5}


def predict(params, data):
    return params["a"] * data["Tm"].to_numpy(float) / 1000.0
