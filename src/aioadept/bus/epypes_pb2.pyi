from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Attribute(_message.Message):
    __slots__ = ("type", "key", "str_val", "double_val", "int_val")
    class Type(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
        __slots__ = ()
        STRING: _ClassVar[Attribute.Type]
        DOUBLE: _ClassVar[Attribute.Type]
        INT: _ClassVar[Attribute.Type]
    STRING: Attribute.Type
    DOUBLE: Attribute.Type
    INT: Attribute.Type
    TYPE_FIELD_NUMBER: _ClassVar[int]
    KEY_FIELD_NUMBER: _ClassVar[int]
    STR_VAL_FIELD_NUMBER: _ClassVar[int]
    DOUBLE_VAL_FIELD_NUMBER: _ClassVar[int]
    INT_VAL_FIELD_NUMBER: _ClassVar[int]
    type: Attribute.Type
    key: str
    str_val: str
    double_val: float
    int_val: int
    def __init__(self, type: _Optional[_Union[Attribute.Type, str]] = ..., key: _Optional[str] = ..., str_val: _Optional[str] = ..., double_val: _Optional[float] = ..., int_val: _Optional[int] = ...) -> None: ...

class AttributeList(_message.Message):
    __slots__ = ("entries",)
    ENTRIES_FIELD_NUMBER: _ClassVar[int]
    entries: _containers.RepeatedCompositeFieldContainer[Attribute]
    def __init__(self, entries: _Optional[_Iterable[_Union[Attribute, _Mapping]]] = ...) -> None: ...

class Event(_message.Message):
    __slots__ = ("type", "id", "attributes")
    TYPE_FIELD_NUMBER: _ClassVar[int]
    ID_FIELD_NUMBER: _ClassVar[int]
    ATTRIBUTES_FIELD_NUMBER: _ClassVar[int]
    type: str
    id: str
    attributes: AttributeList
    def __init__(self, type: _Optional[str] = ..., id: _Optional[str] = ..., attributes: _Optional[_Union[AttributeList, _Mapping]] = ...) -> None: ...

class Image(_message.Message):
    __slots__ = ("bytes", "id", "format", "attributes")
    BYTES_FIELD_NUMBER: _ClassVar[int]
    ID_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    ATTRIBUTES_FIELD_NUMBER: _ClassVar[int]
    bytes: bytes
    id: str
    format: str
    attributes: AttributeList
    def __init__(self, bytes: _Optional[bytes] = ..., id: _Optional[str] = ..., format: _Optional[str] = ..., attributes: _Optional[_Union[AttributeList, _Mapping]] = ...) -> None: ...
