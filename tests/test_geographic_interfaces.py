"""Jazzy's geographic_msgs, built from its definitions where the environment lacks them
(``interfaces/geographic_msgs``; nav2_msgs' FollowGPSWaypoints needs it): every type imports and
has the type hash of the released package, in the built type descriptions and on DDS."""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import pytest

from .interface_hashes import announced_hash, built_hashes

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "geographic_msgs"
#: RIHS01 hashes of the released geographic_msgs 1.0.x, by type under ``geographic_msgs/``
#: (generated from its ros2 branch; GeoPoint's and GeoPose's also as a Jazzy install lists them).
RELEASED = {
    "msg/BoundingBox": "RIHS01_80a85827e595325bd0427f2fa1aa38b70f12d95640d1739db51fe020a407daa6",
    "msg/GeoPath": "RIHS01_da06a03e5d5f28200cf0dc031155a9ceaf644e8615c4dcd1f04d689f86c064e3",
    "msg/GeoPoint": "RIHS01_602c647cf87bbe95a0231b459b5ac30051875d07c0c740b31ad7a8c4662b971e",
    "msg/GeoPointStamped": "RIHS01_ebe562b30db6fadf7b136d11c0c5bcccf393d24fa48874346bed64e58b6dedcf",
    "msg/GeoPose": "RIHS01_8052786d7663e225e38926f7d05716046c931572c25e557d4f70dca55b972626",
    "msg/GeoPoseStamped": "RIHS01_a8e603c050fa992a74283bb462a96fe9d2b151b7a67b14d77250ed7cb4ed96b7",
    "msg/GeoPoseWithCovariance": "RIHS01_e5a071a4c061688377f825b777166e80c3e380aa9e41e1fac0695f54415ee474",
    "msg/GeoPoseWithCovarianceStamped": "RIHS01_e8e87d7bc02d092be564be3b6a2ca2302ff6997a82b996e4c6a9052b88e09aac",
    "msg/GeographicMap": "RIHS01_faeade360ec39eef5736878d91041b90b6accf6c49e3165168504f8af91fb458",
    "msg/GeographicMapChanges": "RIHS01_ab15a12affd34c1393654fba10e98a2f55a5662a63c00930fd7cae3714fd6b28",
    "msg/KeyValue": "RIHS01_7b60e465ab0a5d8108595762d05ee5f8c9da8b7ffed921d6f91262f384bee24b",
    "msg/MapFeature": "RIHS01_925101fc45bc3a1ac2fb3604fa91b79913722e44378421a1658649cbe0ba0454",
    "msg/RouteNetwork": "RIHS01_a59545219389a59cb70ba02c18b3b15448d681a1c9cd19f5e23a306acea6ffba",
    "msg/RoutePath": "RIHS01_e4b22c836b4d9a9e86f6977f4cc78db9a75697fe8e0a6b5371c51dcf7eaba3fe",
    "msg/RouteSegment": "RIHS01_c93d23babd3ce20de7190fd427c1eb5c0b9347ef43e1292c3437bf6aaa45ee57",
    "msg/WayPoint": "RIHS01_af6f3c9c30db80cb8680f60ef40ec5e11c9d4b4d246aa664478988f509b96347",
    "srv/GetGeoPath": "RIHS01_e0c1a08df29cbfcbddfc0180362e4d15eda8c528896f99a15d81f6bb0b0aa5d8",
    "srv/GetGeoPath_Event": "RIHS01_3e67151de98e8f7cc7cec45264210b9e14d6a2b1de3efbf3baee021e9cb96507",
    "srv/GetGeoPath_Request": "RIHS01_8811712609bb7e10bab5f04d54b98c6d1177e09edfe1cc15896c4f6602719da4",
    "srv/GetGeoPath_Response": "RIHS01_6b56fccb056ca7f50447b8099bc1d317c91387dac7b10062cfa23804eea1a4e7",
    "srv/GetGeographicMap": "RIHS01_5bbe97489ec3161d313e125a49088ca995191eb18d3c167b3b630f2e9f221fc9",
    "srv/GetGeographicMap_Event": "RIHS01_1b11d3417972afc07c1fda95e0c7d1a1990fdba3fff94ff751bc7d9d3f98d2a5",
    "srv/GetGeographicMap_Request": "RIHS01_1429130e894587b295fa585409d38c08978aeff7c90cd71161e2ef06a80cdbd4",
    "srv/GetGeographicMap_Response": "RIHS01_c53107b9085edaacd3169608f1aa1207075a3afea9c817e62546f1c2d8f560b4",
    "srv/GetRoutePlan": "RIHS01_1c08a73149a0ed4b8a9686cebcd71b3913efde16db34007c98ccd9b7517b8957",
    "srv/GetRoutePlan_Event": "RIHS01_a53dc0104042fe787e87de653a7b3e6d21c2befa3584fad1fb60a05a192c4662",
    "srv/GetRoutePlan_Request": "RIHS01_f8ddbc3e0596572e0a35e4cc466defbf618ca52345c3daf48393c2b270011e88",
    "srv/GetRoutePlan_Response": "RIHS01_5f07b9f98fffca3407b0a75a1369e0270b3fb0bb0cd06921efdb15f6e8f0172a",
    "srv/UpdateGeographicMap": "RIHS01_017e6eb2e5f7e6735c9900d270f3916f6750ccde03cdde3d04651946e464840a",
    "srv/UpdateGeographicMap_Event": "RIHS01_709cd30139b92c30124e5992a75a39a17d4c3fe0a6576b67ca6e8fa2245e9c04",
    "srv/UpdateGeographicMap_Request": "RIHS01_a1329457bfaa245a8ce027d30a823c7300bacfa2ae34170fda39541f811d72dd",
    "srv/UpdateGeographicMap_Response": "RIHS01_7c64830cb80f6afae8dc0d82beb18ae688130fb315ba4a84f3b4f91af8ca35b1",
}


def definitions() -> list[tuple[str, str]]:
    return [(kind, path.stem) for kind in ("msg", "srv") for path in sorted((INTERFACES / kind).glob(f"*.{kind}"))]


def test_every_type_of_the_release_is_there_and_imports() -> None:
    assert len(definitions()) == 20  # 16 messages, 4 services
    for kind, name in definitions():
        assert hasattr(importlib.import_module(f"geographic_msgs.{kind}"), name)


def test_every_type_hash_is_the_releases() -> None:
    built = built_hashes("geographic_msgs")
    assert len(RELEASED) == 16 + 4 * 4  # a service: itself, its request, response and event
    assert {name: built.get(name) for name in RELEASED} == RELEASED


@pytest.mark.ros
def test_a_publisher_announces_the_releases_hash_on_dds(ros_node: Any) -> None:
    from geographic_msgs.msg import GeoPoseStamped
    from nav2_msgs.action import FollowGPSWaypoints

    assert announced_hash(ros_node, GeoPoseStamped, "/geographic_interfaces_test") == RELEASED["msg/GeoPoseStamped"]
    # What BasicNavigator.followGpsWaypoints() sends: geographic_msgs/GeoPose goals.
    goal = FollowGPSWaypoints.Goal()
    assert goal.get_fields_and_field_types()["gps_poses"] == "sequence<geographic_msgs/GeoPose>"
