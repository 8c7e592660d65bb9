"""The lining as a structure: section forces on cuts through it (:mod:`.forces`), segment
joints (:mod:`.joints`) and the EN 1992 checks of its sections and joints (:mod:`.design`)."""
