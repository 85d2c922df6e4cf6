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
    __slots__ = ("x", "y", "z", "nx", "ny", "nz", "penetration", "normal_force", "friction_force_t1", "friction_force_t2", "fx", "fy", "fz", "geom1", "geom2")
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
    GEOM1_FIELD_NUMBER: _ClassVar[int]
    GEOM2_FIELD_NUMBER: _ClassVar[int]
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
    geom1: int
    geom2: int
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., nx: _Optional[float] = ..., ny: _Optional[float] = ..., nz: _Optional[float] = ..., penetration: _Optional[float] = ..., normal_force: _Optional[float] = ..., friction_force_t1: _Optional[float] = ..., friction_force_t2: _Optional[float] = ..., fx: _Optional[float] = ..., fy: _Optional[float] = ..., fz: _Optional[float] = ..., geom1: _Optional[int] = ..., geom2: _Optional[int] = ...) -> None: ...

class Contacts(_message.Message):
    __slots__ = ("points",)
    POINTS_FIELD_NUMBER: _ClassVar[int]
    points: _containers.RepeatedCompositeFieldContainer[ContactPoint]
    def __init__(self, points: _Optional[_Iterable[_Union[ContactPoint, _Mapping]]] = ...) -> None: ...

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

class Work(_message.Message):
    __slots__ = ("contact_normal", "contact_friction", "springs", "damping", "limits", "equality", "friction_loss", "actuators", "fluid", "gravity_compensation", "solver")
    CONTACT_NORMAL_FIELD_NUMBER: _ClassVar[int]
    CONTACT_FRICTION_FIELD_NUMBER: _ClassVar[int]
    SPRINGS_FIELD_NUMBER: _ClassVar[int]
    DAMPING_FIELD_NUMBER: _ClassVar[int]
    LIMITS_FIELD_NUMBER: _ClassVar[int]
    EQUALITY_FIELD_NUMBER: _ClassVar[int]
    FRICTION_LOSS_FIELD_NUMBER: _ClassVar[int]
    ACTUATORS_FIELD_NUMBER: _ClassVar[int]
    FLUID_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_COMPENSATION_FIELD_NUMBER: _ClassVar[int]
    SOLVER_FIELD_NUMBER: _ClassVar[int]
    contact_normal: float
    contact_friction: float
    springs: float
    damping: float
    limits: float
    equality: float
    friction_loss: float
    actuators: float
    fluid: float
    gravity_compensation: float
    solver: float
    def __init__(self, contact_normal: _Optional[float] = ..., contact_friction: _Optional[float] = ..., springs: _Optional[float] = ..., damping: _Optional[float] = ..., limits: _Optional[float] = ..., equality: _Optional[float] = ..., friction_loss: _Optional[float] = ..., actuators: _Optional[float] = ..., fluid: _Optional[float] = ..., gravity_compensation: _Optional[float] = ..., solver: _Optional[float] = ...) -> None: ...

class SideState(_message.Message):
    __slots__ = ("values",)
    VALUES_FIELD_NUMBER: _ClassVar[int]
    values: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, values: _Optional[_Iterable[float]] = ...) -> None: ...

class Impact(_message.Message):
    __slots__ = ("side1", "kind1", "side2", "kind2", "geom1", "geom2", "onset_ns", "release_ns", "v_in", "v_out", "work_compression", "work_restitution", "work_friction", "peak_force", "impulse", "max_penetration", "steps", "open", "point_in", "normal_in", "point_out", "normal_out", "side1_in", "side2_in", "side1_out", "side2_out")
    SIDE1_FIELD_NUMBER: _ClassVar[int]
    KIND1_FIELD_NUMBER: _ClassVar[int]
    SIDE2_FIELD_NUMBER: _ClassVar[int]
    KIND2_FIELD_NUMBER: _ClassVar[int]
    GEOM1_FIELD_NUMBER: _ClassVar[int]
    GEOM2_FIELD_NUMBER: _ClassVar[int]
    ONSET_NS_FIELD_NUMBER: _ClassVar[int]
    RELEASE_NS_FIELD_NUMBER: _ClassVar[int]
    V_IN_FIELD_NUMBER: _ClassVar[int]
    V_OUT_FIELD_NUMBER: _ClassVar[int]
    WORK_COMPRESSION_FIELD_NUMBER: _ClassVar[int]
    WORK_RESTITUTION_FIELD_NUMBER: _ClassVar[int]
    WORK_FRICTION_FIELD_NUMBER: _ClassVar[int]
    PEAK_FORCE_FIELD_NUMBER: _ClassVar[int]
    IMPULSE_FIELD_NUMBER: _ClassVar[int]
    MAX_PENETRATION_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    OPEN_FIELD_NUMBER: _ClassVar[int]
    POINT_IN_FIELD_NUMBER: _ClassVar[int]
    NORMAL_IN_FIELD_NUMBER: _ClassVar[int]
    POINT_OUT_FIELD_NUMBER: _ClassVar[int]
    NORMAL_OUT_FIELD_NUMBER: _ClassVar[int]
    SIDE1_IN_FIELD_NUMBER: _ClassVar[int]
    SIDE2_IN_FIELD_NUMBER: _ClassVar[int]
    SIDE1_OUT_FIELD_NUMBER: _ClassVar[int]
    SIDE2_OUT_FIELD_NUMBER: _ClassVar[int]
    side1: str
    kind1: str
    side2: str
    kind2: str
    geom1: str
    geom2: str
    onset_ns: int
    release_ns: int
    v_in: float
    v_out: float
    work_compression: float
    work_restitution: float
    work_friction: float
    peak_force: float
    impulse: float
    max_penetration: float
    steps: int
    open: bool
    point_in: _containers.RepeatedScalarFieldContainer[float]
    normal_in: _containers.RepeatedScalarFieldContainer[float]
    point_out: _containers.RepeatedScalarFieldContainer[float]
    normal_out: _containers.RepeatedScalarFieldContainer[float]
    side1_in: SideState
    side2_in: SideState
    side1_out: SideState
    side2_out: SideState
    def __init__(self, side1: _Optional[str] = ..., kind1: _Optional[str] = ..., side2: _Optional[str] = ..., kind2: _Optional[str] = ..., geom1: _Optional[str] = ..., geom2: _Optional[str] = ..., onset_ns: _Optional[int] = ..., release_ns: _Optional[int] = ..., v_in: _Optional[float] = ..., v_out: _Optional[float] = ..., work_compression: _Optional[float] = ..., work_restitution: _Optional[float] = ..., work_friction: _Optional[float] = ..., peak_force: _Optional[float] = ..., impulse: _Optional[float] = ..., max_penetration: _Optional[float] = ..., steps: _Optional[int] = ..., open: _Optional[bool] = ..., point_in: _Optional[_Iterable[float]] = ..., normal_in: _Optional[_Iterable[float]] = ..., point_out: _Optional[_Iterable[float]] = ..., normal_out: _Optional[_Iterable[float]] = ..., side1_in: _Optional[_Union[SideState, _Mapping]] = ..., side2_in: _Optional[_Union[SideState, _Mapping]] = ..., side1_out: _Optional[_Union[SideState, _Mapping]] = ..., side2_out: _Optional[_Union[SideState, _Mapping]] = ...) -> None: ...
