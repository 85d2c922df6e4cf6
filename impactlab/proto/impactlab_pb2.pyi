from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class BodyState(_message.Message):
    __slots__ = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    QW_FIELD_NUMBER: _ClassVar[int]
    QX_FIELD_NUMBER: _ClassVar[int]
    QY_FIELD_NUMBER: _ClassVar[int]
    QZ_FIELD_NUMBER: _ClassVar[int]
    VX_FIELD_NUMBER: _ClassVar[int]
    VY_FIELD_NUMBER: _ClassVar[int]
    VZ_FIELD_NUMBER: _ClassVar[int]
    WX_FIELD_NUMBER: _ClassVar[int]
    WY_FIELD_NUMBER: _ClassVar[int]
    WZ_FIELD_NUMBER: _ClassVar[int]
    x: float
    y: float
    z: float
    qw: float
    qx: float
    qy: float
    qz: float
    vx: float
    vy: float
    vz: float
    wx: float
    wy: float
    wz: float
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., qw: _Optional[float] = ..., qx: _Optional[float] = ..., qy: _Optional[float] = ..., qz: _Optional[float] = ..., vx: _Optional[float] = ..., vy: _Optional[float] = ..., vz: _Optional[float] = ..., wx: _Optional[float] = ..., wy: _Optional[float] = ..., wz: _Optional[float] = ...) -> None: ...

class ContactPoint(_message.Message):
    __slots__ = ("x", "y", "z", "nx", "ny", "nz", "penetration", "normal_force", "friction_force_t1", "friction_force_t2", "fx", "fy", "fz")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    NX_FIELD_NUMBER: _ClassVar[int]
    NY_FIELD_NUMBER: _ClassVar[int]
    NZ_FIELD_NUMBER: _ClassVar[int]
    PENETRATION_FIELD_NUMBER: _ClassVar[int]
    NORMAL_FORCE_FIELD_NUMBER: _ClassVar[int]
    FRICTION_FORCE_T1_FIELD_NUMBER: _ClassVar[int]
    FRICTION_FORCE_T2_FIELD_NUMBER: _ClassVar[int]
    FX_FIELD_NUMBER: _ClassVar[int]
    FY_FIELD_NUMBER: _ClassVar[int]
    FZ_FIELD_NUMBER: _ClassVar[int]
    x: float
    y: float
    z: float
    nx: float
    ny: float
    nz: float
    penetration: float
    normal_force: float
    friction_force_t1: float
    friction_force_t2: float
    fx: float
    fy: float
    fz: float
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., nx: _Optional[float] = ..., ny: _Optional[float] = ..., nz: _Optional[float] = ..., penetration: _Optional[float] = ..., normal_force: _Optional[float] = ..., friction_force_t1: _Optional[float] = ..., friction_force_t2: _Optional[float] = ..., fx: _Optional[float] = ..., fy: _Optional[float] = ..., fz: _Optional[float] = ...) -> None: ...

class Contact(_message.Message):
    __slots__ = ("geom1", "geom2", "body1", "body2", "points")
    GEOM1_FIELD_NUMBER: _ClassVar[int]
    GEOM2_FIELD_NUMBER: _ClassVar[int]
    BODY1_FIELD_NUMBER: _ClassVar[int]
    BODY2_FIELD_NUMBER: _ClassVar[int]
    POINTS_FIELD_NUMBER: _ClassVar[int]
    geom1: str
    geom2: str
    body1: str
    body2: str
    points: _containers.RepeatedCompositeFieldContainer[ContactPoint]
    def __init__(self, geom1: _Optional[str] = ..., geom2: _Optional[str] = ..., body1: _Optional[str] = ..., body2: _Optional[str] = ..., points: _Optional[_Iterable[_Union[ContactPoint, _Mapping]]] = ...) -> None: ...

class Energy(_message.Message):
    __slots__ = ("kinetic", "potential", "total")
    KINETIC_FIELD_NUMBER: _ClassVar[int]
    POTENTIAL_FIELD_NUMBER: _ClassVar[int]
    TOTAL_FIELD_NUMBER: _ClassVar[int]
    kinetic: float
    potential: float
    total: float
    def __init__(self, kinetic: _Optional[float] = ..., potential: _Optional[float] = ..., total: _Optional[float] = ...) -> None: ...

class Clearance(_message.Message):
    __slots__ = ("distance",)
    DISTANCE_FIELD_NUMBER: _ClassVar[int]
    distance: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, distance: _Optional[_Iterable[float]] = ...) -> None: ...

class ContactWork(_message.Message):
    __slots__ = ("start_ns", "end_ns", "work_compression", "work_restitution", "v_start", "v_end", "open")
    START_NS_FIELD_NUMBER: _ClassVar[int]
    END_NS_FIELD_NUMBER: _ClassVar[int]
    WORK_COMPRESSION_FIELD_NUMBER: _ClassVar[int]
    WORK_RESTITUTION_FIELD_NUMBER: _ClassVar[int]
    V_START_FIELD_NUMBER: _ClassVar[int]
    V_END_FIELD_NUMBER: _ClassVar[int]
    OPEN_FIELD_NUMBER: _ClassVar[int]
    start_ns: int
    end_ns: int
    work_compression: float
    work_restitution: float
    v_start: float
    v_end: float
    open: bool
    def __init__(self, start_ns: _Optional[int] = ..., end_ns: _Optional[int] = ..., work_compression: _Optional[float] = ..., work_restitution: _Optional[float] = ..., v_start: _Optional[float] = ..., v_end: _Optional[float] = ..., open: _Optional[bool] = ...) -> None: ...
