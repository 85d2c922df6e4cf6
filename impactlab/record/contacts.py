"""MuJoCo's contacts and constraint forces at every simulated step, decoded per chunk."""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import mujoco
import numpy as np

_FIELDS = ("dist", "pos", "frame", "friction", "dim", "geom", "flex", "exclude", "efc_address")
_PROBE = """<mujoco><worldbody><geom type="plane" size="1 1 1"/>
<body pos="0 0 0.05"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>"""


def _address(array: np.ndarray) -> int:
    return int(array.__array_interface__["data"][0])


def _learn_dtype() -> np.dtype:
    """The layout of MuJoCo's `mjContact` (the fields read here), from the bindings' own
    field views of a model with one contact: right for whatever MuJoCo version runs."""
    model = mujoco.MjModel.from_xml_string(_PROBE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    contact = data.contact
    base = _address(contact.dist)
    views = [getattr(contact, name) for name in _FIELDS]
    return np.dtype(
        {
            "names": list(_FIELDS),
            "formats": [(v.dtype, v.shape[1:]) if v.ndim > 1 else v.dtype for v in views],
            "offsets": [_address(v) - base for v in views],
            "itemsize": contact.dist.strides[0],
        }
    )


CONTACT_DTYPE = _learn_dtype()


class ContactTape:
    """Copies each step's contacts and constraint rows into chunk buffers, one copy each.

    MuJoCo keeps `mjData.contact` at the start of its arena; `_contacts` views it as a
    structured array (`CONTACT_DTYPE`), so a step's contacts are copied in one operation.
    Per step: its numbers of contacts and rows (`ncon`, `nefc`). Per constraint row:
    MuJoCo's force, its velocity J v at the step's start and J v' after the step
    (`mj_mulJacVec` with the new velocity), with `types` its constraint type, and for RK4
    J v before any contact force acted (`arrive`, the other integrators' is J v: at the
    previous step's start, whose later stages already meet a contact the start state shows).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, *, types: bool) -> None:
        self.model, self.data, self.types = model, data, types
        self.rk4 = int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4)
        self._contacts: np.ndarray | None = None
        self._jacobian: tuple[int, int, tuple[np.ndarray, ...]] = (0, 0, ())
        self.contact = np.empty((64, CONTACT_DTYPE.itemsize), np.uint8)  # mjContact bytes
        self.force = np.empty(256)
        self.vel = np.empty(256)
        self.vel_after = np.empty(256)
        self.arrive = np.empty(256)  # RK4's (`after_step`)
        self.type = np.empty(256, np.int32)
        self.reset(0)

    def reset(self, nstep: int) -> None:
        """Empty the buffers for a chunk of `nstep` steps (they keep the room they grew to)."""
        self.ncontact = self.nrow = 0
        self.ncon, self.nefc = np.zeros(nstep, np.int64), np.zeros(nstep, np.int64)

    def _view(self) -> np.ndarray:
        """The contact array of `data` as rows of bytes, one per mjContact (a plain copy of
        its rows is a memcpy; `decode` reads the fields through `CONTACT_DTYPE`)."""
        base = _address(self.data.contact.dist)
        size = CONTACT_DTYPE.itemsize
        memory = (ctypes.c_char * (int(self.data.narena) // size * size)).from_address(base)
        view: np.ndarray = np.frombuffer(memoryview(memory), np.uint8).reshape(-1, size)
        return view

    def add(self, step: int, *, after: bool = True) -> None:
        """Copy the contacts and constraint rows MuJoCo has for step `step` (its start
        state's, as `mj_step` leaves them for every integrator but RK4), and with `after`
        J v' for the velocity after the step; without (RK4, whose stages leave another
        state's Jacobian), the Jacobian is kept for `after_step` to apply."""
        data = self.data
        ncon, nefc = data.ncon, data.nefc
        self.nefc[step] = nefc
        r = self.nrow
        end = self.nrow = r + nefc
        if end > self.force.size:
            self.force, self.vel = _grow(self.force, end), _grow(self.vel, end)
            self.vel_after, self.type = _grow(self.vel_after, end), _grow(self.type, end)
            self.arrive = _grow(self.arrive, end)
        self.force[r:end] = data.efc_force
        self.vel[r:end] = data.efc_vel
        if after:
            mujoco.mj_mulJacVec(self.model, data, self.vel_after[r:end], data.qvel)
        else:
            self._jacobian = (r, nefc, self._jacobian_rows())
        if self.types:
            self.type[r:end] = data.efc_type
        if ncon:
            self.ncon[step] = ncon
            k = self.ncontact
            if self._contacts is None:
                self._contacts = self._view()
            if k + ncon > len(self.contact):
                self.contact = _grow(self.contact, k + ncon)
            self.contact[k : k + ncon] = self._contacts[:ncon]
            self.ncontact = k + ncon

    def _jacobian_rows(self) -> tuple[np.ndarray, ...]:
        """A copy of the constraint Jacobian (dense rows, or MuJoCo's sparse rows)."""
        data, nefc = self.data, int(self.data.nefc)
        if mujoco.mj_isSparse(self.model):
            nnz = data.efc_J_rownnz[:nefc].copy()
            adr = data.efc_J_rowadr[:nefc].copy()
            return nnz, adr, data.efc_J_colind.copy(), data.efc_J.copy()
        return (data.efc_J[: nefc * self.model.nv].reshape(nefc, self.model.nv).copy(),)

    def after_step(self, qvel: np.ndarray, before: np.ndarray) -> None:
        """For the rows kept by `add(after=False)`: J v' with the step's new velocity, and
        `arrive`, J v with the velocity at the previous step's start (`before`)."""
        r, nefc, rows = self._jacobian
        self.vel_after[r : r + nefc] = self._times_jacobian(rows, nefc, qvel)
        self.arrive[r : r + nefc] = self._times_jacobian(rows, nefc, before)

    @staticmethod
    def _times_jacobian(rows: tuple[np.ndarray, ...], nefc: int, v: np.ndarray) -> np.ndarray:
        """J v for the Jacobian rows kept by `_jacobian_rows` (dense or sparse)."""
        if len(rows) == 1:
            product: np.ndarray = rows[0] @ v
            return product
        nnz, adr, col, values = rows
        end = int(adr[-1] + nnz[-1])
        products = values[:end] * v[col[:end]]
        starts = adr[nnz > 0]
        sums = np.zeros(nefc)
        if starts.size:
            sums[nnz > 0] = np.add.reduceat(products, starts)
        return sums

    def check(self) -> None:
        """Raise if MuJoCo moved its contact array (the view would read stale memory)."""
        view = self._contacts
        if (
            view is not None
            and self.data.ncon
            and _address(self.data.contact.dist) != _address(view)
        ):
            raise RuntimeError("MuJoCo's contact array moved: the recorder cannot read it")


def _grow(array: np.ndarray, need: int) -> np.ndarray:
    """`array` with room for `need` rows at least (twice its rows, if more)."""
    out = np.empty((max(need, 2 * len(array)), *array.shape[1:]), array.dtype)
    out[: len(array)] = array
    return out


@dataclass(frozen=True)
class StepContacts:
    """A chunk's active contacts, one entry per contact and step (local step, ascending).

    Forces in N and velocities in m/s along the contact frame (normal from side 1 to side
    2); `v_start`/`v_end` the relative normal velocity at the step's start and end (< 0:
    approaching), `v_arrive` before any contact force acted (`ContactTape`);
    `power_normal`/`power_friction` the power of the normal and friction forces over the
    step (W, at the step's mean velocity). Sides are geom ids, or -1 for a flex (`flex1`,
    `flex2` then give it).
    """

    step: np.ndarray
    geom1: np.ndarray
    geom2: np.ndarray
    flex1: np.ndarray
    flex2: np.ndarray
    penetration: np.ndarray
    pos: np.ndarray
    frame: np.ndarray
    force: np.ndarray  # (n, 3): normal, friction along the frame's two tangents
    v_start: np.ndarray
    v_end: np.ndarray
    v_arrive: np.ndarray
    power_normal: np.ndarray
    power_friction: np.ndarray

    def __len__(self) -> int:
        return int(self.step.size)

    def take(self, keep: np.ndarray) -> StepContacts:
        """The entries selected by `keep` (a mask or indices); itself when a mask keeps all."""
        if keep.dtype == bool and keep.all():
            return self
        return StepContacts(*(getattr(self, f)[keep] for f in self.__dataclass_fields__))


def decode(tape: ContactTape, pyramidal: bool) -> tuple[StepContacts, np.ndarray, np.ndarray]:
    """The tape's contacts, and each constraint row's power and type (W, per row).

    A contact's rows start at its `efc_address`: one (frictionless), `dim` (elliptic: the
    normal first) or 2 (dim - 1) (pyramidal: the edges, whose forces sum to the normal
    force; friction j is mu_j (f_2j - f_2j+1), and the normal velocity is the mean of the
    first two rows'). Contacts outside the constraints (`exclude`, in a margin's gap) are left
    out. Returns (contacts, power per row, whether each row belongs to a contact).
    """
    raw = tape.contact[: tape.ncontact].view(CONTACT_DTYPE)[:, 0]
    n_rows = tape.nrow
    force, vel, after = tape.force[:n_rows], tape.vel[:n_rows], tape.vel_after[:n_rows]
    arrive = tape.arrive[:n_rows] if tape.rk4 else vel
    power = force * 0.5 * (vel + after)
    active = (raw["exclude"] == 0) & (raw["efc_address"] >= 0)
    step = np.repeat(np.arange(tape.ncon.size), tape.ncon)
    if not active.all():  # (a copy of every contact's whole struct otherwise)
        raw, step = raw[active], step[active]
    # each contact's first row in this chunk's row buffer: rows of one step are contiguous
    first_row = (np.cumsum(tape.nefc) - tape.nefc)[step] + raw["efc_address"]
    dim = raw["dim"].astype(np.int64)
    friction_dims = np.where(dim > 1, dim - 1, 0)
    nrows = np.where(dim == 1, 1, 2 * friction_dims if pyramidal else dim)
    owner = np.repeat(np.arange(raw.size), nrows)
    rows = np.repeat(first_row - np.cumsum(nrows) + nrows, nrows) + np.arange(owner.size)
    in_contact = np.zeros(n_rows, bool)
    in_contact[rows] = True
    total_power = np.bincount(owner, power[rows], raw.size)
    f3 = np.zeros((raw.size, 3))
    if pyramidal:
        f3[:, 0] = np.bincount(owner, force[rows], raw.size)
        paired = np.minimum(dim, 2) == 2  # the normal velocity: mean of the first two rows
        second = first_row + paired
        v_start = 0.5 * (vel[first_row] + vel[second])
        v_end = 0.5 * (after[first_row] + after[second])
        v_arrive = 0.5 * (arrive[first_row] + arrive[second])
        mu = raw["friction"]
        for j in range(2):
            has = friction_dims > j
            a = first_row[has] + 2 * j
            f3[has, 1 + j] = mu[has, j] * (force[a] - force[a + 1])
    else:
        f3[:, 0] = force[first_row]
        v_start, v_end, v_arrive = vel[first_row], after[first_row], arrive[first_row]
        for j in range(2):
            has = friction_dims > j
            f3[has, 1 + j] = force[first_row[has] + 1 + j]
    power_normal = f3[:, 0] * 0.5 * (v_start + v_end)
    contacts = StepContacts(
        step=step,
        geom1=raw["geom"][:, 0].astype(np.int64),
        geom2=raw["geom"][:, 1].astype(np.int64),
        flex1=raw["flex"][:, 0].astype(np.int64),
        flex2=raw["flex"][:, 1].astype(np.int64),
        penetration=-raw["dist"],
        pos=raw["pos"].copy(),
        frame=raw["frame"].copy(),
        force=f3,
        v_start=v_start,
        v_end=v_end,
        v_arrive=v_arrive,
        power_normal=power_normal,
        power_friction=total_power - power_normal,
    )
    return contacts, power, in_contact
