"""A drive's object dictionary as its EDS or DCF describes it, read once with canopen's EDS
import and asked strictly: an object or sub-index is there only when the file lists it.

canopen's `ODArray` makes up members for any sub-index 1..255 once sub-index 1 exists (it reads
an array's length from the device); a plan made from the file must not, so `entry()` takes an
array's members from the file's sections only. What a file says of an entry: its data type,
its access type (`rw`, `wo`, `ro`, `const`), whether it may be PDO-mapped, its value (a DCF's
`ParameterValue`, else the EDS's `DefaultValue`) and its limits.

`read_dictionary()` turns every way a file can fail to be an object dictionary (missing, not
text, not an EDS, a section canopen cannot parse) into one `DictionaryError` line naming the
file. Pure: no bus.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import DictionaryError, DriveError

if TYPE_CHECKING:
    from canopen.objectdictionary import ObjectDictionary, ODArray, ODRecord, ODVariable
    from canopen.pdo import PdoBase, PdoMaps

__all__ = ['Entry', 'entry', 'mapping_capacity', 'pdo_maps', 'read_dictionary', 'device_name']

MAX_EDS_BYTES = 4 << 20        # a vendor's EDS is a few hundred kB; anything larger is not one


def read_dictionary(path: str | Path, node_id: int | None = None) -> ObjectDictionary:
    """The object dictionary of the EDS/DCF at `path` ($NODEID as `node_id`). DictionaryError
    (one line naming the file) when it is missing, not text, or not an EDS canopen reads."""
    # lazy: canopen costs 70-120 ms (python -X importtime) and `planter commission --help` and
    # `planter drive check --help` load this module (test_help_opens_nothing)
    import canopen
    path = Path(path)
    where = f'EDS {path}'
    if not path.is_file():
        raise DictionaryError(f'{where} is not a file: allowed the drive\'s EDS or DCF file')
    if path.suffix.lower() not in ('.eds', '.dcf'):
        raise DictionaryError(f'{where}: {path.suffix or "no suffix"} is not an EDS or DCF '
                              'file name: allowed .eds or .dcf')
    try:
        raw = path.read_bytes()[:MAX_EDS_BYTES + 1]
    except OSError as exc:
        raise DictionaryError(f'{where} cannot be read: {exc.strerror or exc}') from None
    if len(raw) > MAX_EDS_BYTES:
        raise DictionaryError(f'{where} is over {MAX_EDS_BYTES >> 20} MiB: not an EDS')
    if b'\x00' in raw:
        raise DictionaryError(f'{where} is not a text file (it holds NUL bytes): an EDS or '
                              'DCF is text (CiA 306)')
    try:
        dictionary = canopen.import_od(str(path), node_id)
    except Exception as exc:          # canopen raises what configparser, int() and open raise
        text = str(exc).splitlines()[0] if str(exc) else ''
        raise DictionaryError(f'{where} is not an EDS canopen can read: {type(exc).__name__}'
                              + (f': {text}' if text else '')) from None
    if 0x1000 not in dictionary:
        raise DictionaryError(f'{where} has no object 1000h (device type): not the EDS of a '
                              'CANopen device')
    return dictionary


@dataclass(frozen=True)
class Entry:
    """One entry as the file describes it."""

    index: int
    subindex: int
    name: str
    data_type: int
    access: str                       # 'rw', 'wo', 'ro', 'const' (lower case)
    mappable: bool
    value: int | None                 # ParameterValue (DCF), else DefaultValue; None: neither
    high_limit: int | None

    @property
    def writable(self) -> bool:
        return 'w' in self.access

    @property
    def address(self) -> str:
        return f'0x{self.index:04X}' + (f':{self.subindex}' if self.subindex else '')


def _kinds() -> tuple[type[ODVariable], type[ODArray]]:
    """canopen's classes of a variable and an array entry."""
    # lazy: as read_dictionary's (a dictionary to ask means canopen is loaded already)
    from canopen.objectdictionary import ODArray, ODVariable
    return ODVariable, ODArray


def _members(obj: ODRecord | ODArray) -> dict[int, ODVariable]:
    """The sub-indices the file itself lists for a record or array."""
    if isinstance(obj, _kinds()[1]):
        return dict(obj.subindices)
    return {sub: obj[sub] for sub in obj}          # an ODRecord lists only its own


def entry(dictionary: ObjectDictionary, index: int, subindex: int = 0) -> Entry | None:
    """The entry `index`:`subindex` as the file lists it, or None when it does not."""
    obj = dictionary.get(index)
    if obj is None:
        return None
    if isinstance(obj, _kinds()[0]):
        if subindex:
            return None
        var = obj
    else:
        member = _members(obj).get(subindex)
        if member is None:
            return None
        var = member
    value = var.value if var.value is not None else var.default
    if value is not None and not isinstance(value, int):
        value = None                              # strings and domains: not ours to use
    return Entry(index, subindex, var.name, int(var.data_type or 0),
                 (var.access_type or 'rw').lower(), bool(var.pdo_mappable), value,
                 var.max if isinstance(var.max, int) else None)


def mapping_capacity(dictionary: ObjectDictionary, mapping_index: int) -> int:
    """How many entries the PDO mapping record `mapping_index` (1600h.., 1A00h..) takes: the
    mapping sub-indices the file lists (1, 2, ... without a gap), at most sub-index 0's high
    limit when it states one; 0 when the record is missing or its mapping is not writable."""
    obj = dictionary.get(mapping_index)
    if obj is None or isinstance(obj, _kinds()[0]):
        return 0
    count = entry(dictionary, mapping_index, 0)
    if count is None or not count.writable:
        return 0
    members = _members(obj)
    listed = 0
    while listed + 1 in members and 'w' in (members[listed + 1].access_type or '').lower():
        listed += 1
    if count.high_limit is not None:
        listed = min(listed, count.high_limit)
    return max(listed, 0)


def device_name(dictionary: ObjectDictionary) -> str:
    """The file's vendor and product names ('' when it gives none)."""
    info = dictionary.device_information
    return ' '.join(part for part in (info.vendor_name, info.product_name) if part).strip()


def pdo_maps(pdos: PdoBase) -> PdoMaps:
    """The maps of a node's RPDOs or TPDOs (canopen's `RPDO` and `TPDO` make theirs when the
    node is made; its base class types them optional)."""
    if pdos.map is None:
        raise DriveError(f'{type(pdos).__name__} of node {pdos.node.id}: no PDO maps')
    return pdos.map
