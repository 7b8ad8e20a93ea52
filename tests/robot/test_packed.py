"""The collision geometry packed as arrays (#28): rebuilt equal, pickled small."""

from __future__ import annotations

import gc
import pickle

import coal
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.packed import pack_geometry


@pytest.fixture(scope="module")
def ur5() -> RobotModel:
    return load_model("ur5")


#: Pinocchio's text archive of one geometry object without its mesh (name, frames,
#: placement, mesh path, scale, colour, material): 1.3 KB measured on the ur5.
OBJECT_BYTES = 2_000


def _mesh_bytes(model: pin.GeometryModel) -> int:
    """Bytes of the meshes' arrays: 24 per vertex (3 float64), 12 per triangle (3 int32)."""
    total = 0
    for obj in model.geometryObjects:
        if isinstance(obj.geometry, coal.BVHModelBase):
            total += 24 * obj.geometry.num_vertices + 12 * obj.geometry.num_tris
    return total


def test_a_packed_model_is_rebuilt_to_the_same_bytes(ur5: RobotModel) -> None:
    """Unpacked where the model is gone: equal, and pickled by coal and Pinocchio byte for byte.

    coal's own pickle of ur5's 7 collision meshes is 9.9 MB (a text archive of the
    vertices, triangles and bounding-volume tree); packed, the arrays plus the
    objects' other fields (measured 0.14 MB).
    """
    model = pickle.loads(pickle.dumps(ur5.collision_model))  # a copy this test drops
    whole = pickle.dumps(model)
    packed = pickle.dumps(pack_geometry(model))
    assert len(packed) <= _mesh_bytes(model) + OBJECT_BYTES * model.ngeoms
    assert len(whole) > 50 * len(packed)
    del model
    gc.collect()  # as in another process: no model to lend
    back = pickle.loads(packed).unpack()
    assert back == ur5.collision_model  # Pinocchio's and coal's comparisons
    assert pickle.dumps(back) == whole  # the same vertices, triangles and tree


def test_the_packing_process_gets_its_model_back(ur5: RobotModel) -> None:
    """A process unpacking a model it packed returns that model (no second copy)."""
    packed = pickle.loads(pickle.dumps(pack_geometry(ur5.collision_model)))
    assert packed.unpack() is ur5.collision_model


def test_primitives_point_clouds_and_pairs_travel() -> None:
    """A box stays as it is; a closed mesh and a point cloud are rebuilt; pairs are kept."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(4, 4)
    mesh.addVertices(corners)
    mesh.addTriangles(np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))
    mesh.endModel()
    cloud = coal.BVHModelOBBRSS()
    cloud.beginModel(0, 4)
    cloud.addVertices(corners * 2.0)
    cloud.endModel()
    model = pin.GeometryModel()
    at = pin.SE3(pin.utils.rotate("z", 0.3), np.array([0.1, 0.2, 0.3]))
    for name, geometry in (("box", coal.Box(0.1, 0.2, 0.3)), ("mesh", mesh), ("cloud", cloud)):
        model.addGeometryObject(pin.GeometryObject(name, 0, 0, at, geometry))
    model.addCollisionPair(pin.CollisionPair(0, 2))
    packed = pack_geometry(model)
    assert [m.index for m in packed.meshes] == [1, 2]
    assert packed.meshes[1].triangles.shape == (0, 3)
    whole = pickle.dumps(model)
    blob = pickle.dumps(packed)
    del model, mesh, cloud
    gc.collect()
    back = pickle.loads(blob).unpack()
    assert pickle.dumps(back) == whole
    assert [type(o.geometry).__name__ for o in back.geometryObjects] == [
        "Box",
        "BVHModelOBBRSS",
        "BVHModelOBBRSS",
    ]
    assert len(back.collisionPairs) == 1


def test_packing_refuses_what_is_not_a_geometry_model(ur5: RobotModel) -> None:
    """A robot (not its geometry) is refused, naming the type."""
    with pytest.raises(ParameterError, match="pinocchio.GeometryModel, got RobotModel"):
        pack_geometry(ur5)  # type: ignore[arg-type]
