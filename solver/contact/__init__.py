"""Contact between ground and lining after Janovský & Procházka (1980): the bolt-point search
and the active-set / Uzawa solve of frictionless contact (:mod:`.bolt`), Coulomb friction
(:mod:`.friction`), floating segments with several rigid modes (:mod:`.floating`) and the
discrete KKT residual every answer is checked by (:mod:`.kkt`)."""
