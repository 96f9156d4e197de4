"""Boundary extraction (paper section 2): labelled holes of a bench to closed geozone contours.

Connected components, boundary holes by local entropy and gap closure
(:mod:`.boundary`), label noise (:mod:`.noise`), the transition field and edge map
(:mod:`.transition`), gradient vector flow
(:mod:`.gvf`), the active contour (:mod:`.snake`) and their assembly per bench
(:mod:`.contours`).
"""
