"""EPypes' own message definitions, built independently of our .proto and generated code.

This mirrors the schema of EPypes' attributes.proto, event.proto and image.proto field by field: no
package (EPypes declares none), three files with imports as in EPypes. It lives in its own DescriptorPool so it never
collides with our generated ``epypes.*`` messages. No protoc is needed at test time.
"""

from __future__ import annotations

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

F = descriptor_pb2.FieldDescriptorProto


def _field(msg, name, number, label, type_, type_name=None):
    f = msg.field.add(name=name, number=number, label=label, type=type_)
    if type_name:
        f.type_name = type_name


def build_pool() -> descriptor_pool.DescriptorPool:
    pool = descriptor_pool.DescriptorPool()

    attrs = descriptor_pb2.FileDescriptorProto(name="attributes.proto", syntax="proto2")
    a = attrs.message_type.add(name="Attribute")
    enum = a.enum_type.add(name="Type")
    for name, num in (("STRING", 1), ("DOUBLE", 2), ("INT", 3)):
        enum.value.add(name=name, number=num)
    _field(a, "type", 1, F.LABEL_REQUIRED, F.TYPE_ENUM, ".Attribute.Type")
    _field(a, "key", 2, F.LABEL_REQUIRED, F.TYPE_STRING)
    _field(a, "str_val", 3, F.LABEL_OPTIONAL, F.TYPE_STRING)
    _field(a, "double_val", 4, F.LABEL_OPTIONAL, F.TYPE_DOUBLE)
    _field(a, "int_val", 5, F.LABEL_OPTIONAL, F.TYPE_INT32)
    al = attrs.message_type.add(name="AttributeList")
    _field(al, "entries", 1, F.LABEL_REPEATED, F.TYPE_MESSAGE, ".Attribute")
    pool.Add(attrs)

    event = descriptor_pb2.FileDescriptorProto(name="event.proto", syntax="proto2", dependency=["attributes.proto"])
    e = event.message_type.add(name="Event")
    _field(e, "type", 1, F.LABEL_REQUIRED, F.TYPE_STRING)
    _field(e, "id", 2, F.LABEL_OPTIONAL, F.TYPE_STRING)
    _field(e, "attributes", 3, F.LABEL_OPTIONAL, F.TYPE_MESSAGE, ".AttributeList")
    pool.Add(event)

    image = descriptor_pb2.FileDescriptorProto(name="image.proto", syntax="proto2", dependency=["attributes.proto"])
    i = image.message_type.add(name="Image")
    _field(i, "bytes", 1, F.LABEL_REQUIRED, F.TYPE_BYTES)
    _field(i, "id", 2, F.LABEL_OPTIONAL, F.TYPE_STRING)
    _field(i, "format", 3, F.LABEL_OPTIONAL, F.TYPE_STRING)
    _field(i, "attributes", 4, F.LABEL_OPTIONAL, F.TYPE_MESSAGE, ".AttributeList")
    pool.Add(image)
    return pool


_POOL = build_pool()
Event = message_factory.GetMessageClass(_POOL.FindMessageTypeByName("Event"))
Image = message_factory.GetMessageClass(_POOL.FindMessageTypeByName("Image"))
Attribute = message_factory.GetMessageClass(_POOL.FindMessageTypeByName("Attribute"))


def add_attribute(pb_message, key, val):
    """EPypes' pbprocess.add_attribute, behaviour for behaviour (exact types; anything else is an error)."""
    attr = pb_message.attributes.entries.add()
    attr.key = key
    if type(val) == str:  # noqa: E721 - EPypes compares exact types
        attr.type = 1
        attr.str_val = val
    elif type(val) == float:  # noqa: E721
        attr.type = 2
        attr.double_val = val
    elif type(val) == int:  # noqa: E721
        attr.type = 3
        attr.int_val = val
    else:
        raise Exception("Wrong value type")
