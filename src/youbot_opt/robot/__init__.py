"""What a robot is (layer L1): parameters, URDF, the loaded model and how to load it again.

Modules: :mod:`.params`, :mod:`.urdf`, :mod:`.model` (:class:`RobotModel`,
its bounds and kinematics), :mod:`.catalogue` (the robots known by name),
:mod:`.load` (``load_model``), :mod:`.source` (:class:`RobotSource`, how result
files name their robot), :mod:`.mimic` and the hostile-URDF policy :mod:`.urdf_check`.
The names of ``__init__.pyi`` are imported on first use (``lazy_loader``), so
importing ``youbot_opt.robot.params`` does not import Pinocchio.

    from youbot_opt.robot import RobotSource
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
