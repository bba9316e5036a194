"""Models shipped with pinlin: URDF files and their scene files (installed as ``pinlin.urdf``).

Every model here was written for pinlin; each file states its provenance and the closed-form
facts the tests check it against.
"""
