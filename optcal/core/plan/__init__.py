"""Planning the positions of a calibration (docs/planning.md): the Fisher information of a set of gravity
directions (:mod:`.fisher`), design criteria D, A, E and targets (:mod:`.criteria`), fixtures, faces and tilts
and the handling order (:mod:`.fixtures`), the exchange algorithm and the refinement on the sphere
(:mod:`.design`), the design problem in the solvers' interface (:mod:`.problem`), robustness to placement
(:mod:`.robust`), next-best pose and "enough yet?" (:mod:`.sequential`), scheme files (:mod:`.schemefile`),
the figure (:mod:`.figure`) and the direction primitives the named schemes share (:mod:`.sphere`). For the
gyroscope, the rotations between a scheme's poses: models, noise, the motions a pair of poses allows, criteria
and plans (:mod:`.gyro`), the candidate motions and their information from the gyroscope problem's Jacobian
(:mod:`.gyro_candidates`), the search over orders and rotations (:mod:`.gyro_search`), and plan files,
recordings that follow a plan and what they determine (:mod:`.gyro_follow`).

All of it is core, except :mod:`.solve`, which runs a registered solver (application layer, imported only by
the command). This file imports nothing, so that :mod:`optcal.core.schemes` can use :mod:`.sphere` cheaply.
"""
