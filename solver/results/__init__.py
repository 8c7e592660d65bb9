"""What a solved case reports: derived measures (:mod:`.post`), the settlement trough
(:mod:`.settlement`) and the CF/UGRID dataset of one case (:mod:`.dataset`)."""
