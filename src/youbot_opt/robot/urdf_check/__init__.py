"""The hostile-URDF policy: a file is read strictly and checked before Pinocchio sees it.

Modules: :mod:`.xml` (the strict XML reader and the error sites),
:mod:`.size` (file size limits: joints, dof, tree depth, XML nesting and
elements), :mod:`.rules` (tree and physics rules), :mod:`.resources` and
:mod:`.meshes` (the one resource and mesh policy), :mod:`.dynamics_defined`
and :mod:`.loader` (the pipeline, :func:`~.loader.load_urdf_strict`).

    from youbot_opt.robot.urdf_check.loader import load_urdf_strict
"""
