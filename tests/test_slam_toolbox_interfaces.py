"""Jazzy's slam_toolbox services, built from their definitions where the environment lacks them
(``interfaces/slam_toolbox``): every type imports, with Jazzy's shapes, constants and, where a
real Jazzy build's generated code was at hand, its type hashes."""
from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "slam_toolbox"
#: RIHS01 hashes of the services as a real build generates them (rosidl's idl__description.c).
JAZZY_HASHES = {
    "AddSubmap": "18ce16d68eaff848",
    "ClearQueue": "5ae7286887351a43cd6265cbd3ec3fdf0074fa6e9f39c17057351b6ab4415477",
    "DeserializePoseGraph": "ec7e27ad873d1c3961583c3288d7fe516bb0035fc9769078657f0377bd55547a",
    "MergeMaps": "711e883fdb23ecf0",
    "Pause": "70971da2d6da308b62b9ef6e4615202d9b3c6e945fcfce5ffded1b45423a236d",
    "Reset": "add9db4656fcb522",
    "ToggleInteractive": "b011a7d5bbf8208c",
}


def services() -> list[str]:
    return [path.stem for path in sorted((INTERFACES / "srv").glob("*.srv"))]


@pytest.mark.parametrize("name", services())
def test_every_definition_imports(name: str):
    assert hasattr(importlib.import_module("slam_toolbox.srv"), name)


def test_every_service_of_jazzy_is_there():
    assert services() == ["AddSubmap", "Clear", "ClearQueue", "DeserializePoseGraph", "LoopClosure", "MergeMaps",
                          "Pause", "Reset", "SaveMap", "SerializePoseGraph", "ToggleInteractive"]


def fields(message: type) -> dict[str, str]:
    return dict(message.get_fields_and_field_types())  # type: ignore[attr-defined]


def test_the_shapes_and_constants_are_jazzys():
    from slam_toolbox.srv import ClearQueue, DeserializePoseGraph, Pause, Reset, SaveMap, SerializePoseGraph

    request = DeserializePoseGraph.Request
    assert fields(request) == {"filename": "string", "match_type": "int8", "initial_pose": "geometry_msgs/Pose2D"}
    assert (request.UNSET, request.START_AT_FIRST_NODE, request.START_AT_GIVEN_POSE,
            request.LOCALIZE_AT_POSE) == (0, 1, 2, 3)
    assert fields(DeserializePoseGraph.Response) == {}  # Jazzy's reply is empty (later ones have a result)
    assert fields(SaveMap.Request) == {"name": "std_msgs/String"}
    assert fields(SaveMap.Response) == {"result": "uint8"}
    assert (SaveMap.Response.RESULT_SUCCESS, SaveMap.Response.RESULT_NO_MAP_RECEIEVD,
            SaveMap.Response.RESULT_UNDEFINED_FAILURE) == (0, 1, 255)
    assert fields(SerializePoseGraph.Request) == {"filename": "string"}
    assert (SerializePoseGraph.Response.RESULT_SUCCESS, SerializePoseGraph.Response.RESULT_FAILED_TO_WRITE_FILE) == \
        (0, 255)
    assert fields(Pause.Request) == {} and fields(Pause.Response) == {"status": "boolean"}
    assert fields(ClearQueue.Request) == {} and fields(ClearQueue.Response) == {"status": "boolean"}
    assert fields(Reset.Request) == {"pause_new_measurements": "boolean"}
    assert Reset.Request().pause_new_measurements is False and Reset.Response.RESULT_SUCCESS == 0


def built_hash(name: str) -> str | None:
    """The hash our build generated (None when the environment's own slam_toolbox was used)."""
    root = Path(__file__).resolve().parent.parent
    description = root / "install" / "slam_toolbox" / "share" / "slam_toolbox" / "srv" / f"{name}.json"
    if not description.is_file():
        return None
    return str(json.loads(description.read_text())["type_hashes"][0]["hash_string"])


@pytest.mark.parametrize("name", sorted(JAZZY_HASHES))
def test_type_hashes_are_a_real_builds(name: str):
    built = built_hash(name)
    if built is None:
        pytest.skip("slam_toolbox comes from the environment, not from interfaces/")
    assert built.removeprefix("RIHS01_").startswith(JAZZY_HASHES[name])
