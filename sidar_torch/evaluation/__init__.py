"""Scoring homography estimators: the scoring protocols and their table (:mod:`.scoring`), the estimators
it can score by name (:mod:`.baselines`) and the versioned test sets (:mod:`.testsets`)."""
