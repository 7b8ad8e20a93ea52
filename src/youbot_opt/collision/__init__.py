"""Collision (layer L2): scenes of obstacles, self-collision pairs, bounding balls, distances.

Modules: :mod:`.shapes` and :mod:`.scene` (:class:`Scene`, furniture URDFs),
:mod:`.scene_file` (the JSON file), :mod:`.pairs` (self-collision, SRDF),
:mod:`.spheres` (bounding balls, cached, with their overshoot),
:mod:`.distance` (smooth CasADi distances), :mod:`.model`
(:class:`CollisionModel`: the distances as a Function of the joints'
placements), :mod:`.exact` (coal's exact distances) and :mod:`.clearance`
(:class:`Clearance`, the spec both optimisers take). ``__init__.pyi``'s names load lazily.

    from youbot_opt.collision import Scene, build_collision_model
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
