"""The committed generated code is what `make proto` produces from the committed .proto files, and it imports with
the pinned protobuf runtime."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

import aioadept.bus

BUS = Path(aioadept.bus.__file__).parent


@pytest.mark.skipif(importlib.util.find_spec("grpc_tools") is None, reason="grpcio-tools (extra 'proto') missing")
def test_generated_code_is_up_to_date(tmp_path):
    from grpc_tools import protoc

    # Same arguments as the Makefile's proto target (paths relative to the include dir matter: they are recorded
    # in the descriptors).
    rc = protoc.main(["protoc", f"-I{BUS}", f"--python_out={tmp_path}", f"--pyi_out={tmp_path}",
                      str(BUS / "epypes.proto"), str(BUS / "aioadept.proto")])
    assert rc == 0
    for name in ("epypes_pb2.py", "epypes_pb2.pyi", "aioadept_pb2.py", "aioadept_pb2.pyi"):
        assert (tmp_path / name).read_bytes() == (BUS / name).read_bytes(), f"{name} is stale: run `make proto`"


def test_generated_modules_import_with_pinned_runtime():
    # Importing runs protobuf's gencode/runtime version check (gencode 7.35.1 needs a runtime >= it).
    from aioadept.bus import aioadept_pb2, epypes_pb2

    assert epypes_pb2.DESCRIPTOR.package == "epypes" and aioadept_pb2.DESCRIPTOR.package == "aioadept"
    assert set(epypes_pb2.DESCRIPTOR.message_types_by_name) == {"Attribute", "AttributeList", "Event", "Image"}
