"""The simulated drive's object dictionary: canopen's `LocalNode` serving any EDS, held to what
the file says and to CiA 301's rules for the PDO parameters, with the SDO abort codes a device
gives:

* an object or sub-index the file does not list: 06020000h / 06090011h (canopen's `ODArray`
  makes up members 1..255 once sub-index 1 exists; here only the file's own count);
* writing a `ro`/`const` entry: 06010002h (LocalNode's own check);
* a PDO mapping (1600h.., 1A00h..): entries changed while the count (sub-index 0) is not 0, or
  the count changed while the PDO is valid: 08000022h (not in the present state); an object
  that does not exist or is not PDO-mappable, or a length unlike its type's: 06040041h; a count
  over the entries the file lists or over 64 bits: 06040042h;
* a PDO's COB-ID bits 0..29 changed while it is valid, a reserved or remote-request-only
  transmission type: 06090030h.
"""
from __future__ import annotations

from typing import Any

import canopen
from canopen.objectdictionary import ODArray, ODVariable
from canopen.sdo import SdoAbortedError

from planter_ros.drive.dictionary import mapping_capacity

__all__ = ['StrictNode', 'ABORT']

ABORT = {
    'no object': 0x06020000, 'no sub-index': 0x06090011, 'read only': 0x06010002,
    'not mappable': 0x06040041, 'pdo length': 0x06040042, 'device state': 0x08000022,
    'value range': 0x06090030,
}
PDO_NOT_VALID = 1 << 31


def _is_mapping(index: int) -> bool:
    return 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF


def _is_comm(index: int) -> bool:
    return 0x1400 <= index <= 0x15FF or 0x1800 <= index <= 0x19FF


class StrictNode(canopen.LocalNode):
    """A LocalNode that is only what its EDS lists and keeps CiA 301's PDO rules (module doc)."""

    def _find_object(self, index: int, subindex: int) -> ODVariable:
        if index not in self.object_dictionary:
            raise SdoAbortedError(ABORT['no object'])
        obj = self.object_dictionary[index]
        if isinstance(obj, ODVariable):
            if subindex:
                raise SdoAbortedError(ABORT['no sub-index'])
            return obj
        members = obj.subindices if isinstance(obj, ODArray) else obj
        if subindex not in members:
            raise SdoAbortedError(ABORT['no sub-index'])
        return obj[subindex]

    def value(self, index: int, subindex: int = 0, default: Any = None) -> Any:
        """The stored value of an entry (as written, else the file's), not a live one;
        `default` when the file lacks it or gives none."""
        try:
            obj = self._find_object(index, subindex)
        except SdoAbortedError:
            return default
        raw = self.data_store.get(index, {}).get(subindex)
        if raw is not None:
            return obj.decode_raw(raw)
        for value in (obj.value, obj.default):
            if value is not None:
                return value
        return default

    def has(self, index: int, subindex: int = 0) -> bool:
        try:
            self._find_object(index, subindex)
            return True
        except SdoAbortedError:
            return False

    def set_data(self, index: int, subindex: int, data: bytes,
                 check_writable: bool = False) -> None:
        if check_writable:              # an SDO download: the device's rules
            obj = self._find_object(index, subindex)
            value = obj.decode_raw(data)
            if obj.writable and isinstance(value, int):     # the PDO entries are UNSIGNEDs
                if _is_mapping(index):
                    self._check_mapping(index, subindex, value)
                elif _is_comm(index):
                    self._check_comm(index, subindex, value)
        super().set_data(index, subindex, data, check_writable)

    def _valid(self, comm_index: int) -> bool:
        cob = self.value(comm_index, 1, PDO_NOT_VALID)
        return not cob & PDO_NOT_VALID

    def _check_mapping(self, index: int, subindex: int, value: int) -> None:
        count = self.value(index, 0, 0)
        if subindex == 0:
            if self._valid(index - 0x200) and value != count:
                raise SdoAbortedError(ABORT['device state'])
            capacity = mapping_capacity(self.object_dictionary, index)
            if value > capacity:
                raise SdoAbortedError(ABORT['pdo length'])
            bits = sum(self.value(index, sub, 0) & 0xFF for sub in range(1, value + 1))
            if bits > 64:
                raise SdoAbortedError(ABORT['pdo length'])
            return
        if count:
            raise SdoAbortedError(ABORT['device state'])
        if value == 0:
            return
        target, sub, length = value >> 16, (value >> 8) & 0xFF, value & 0xFF
        try:
            mapped = self._find_object(target, sub)
        except SdoAbortedError:
            raise SdoAbortedError(ABORT['not mappable']) from None
        if not mapped.pdo_mappable or len(mapped) != length:
            raise SdoAbortedError(ABORT['not mappable'])

    def _check_comm(self, index: int, subindex: int, value: int) -> None:
        if subindex == 1:
            old = self.value(index, 1, PDO_NOT_VALID)
            both_valid = not old & PDO_NOT_VALID and not value & PDO_NOT_VALID
            if both_valid and (old ^ value) & 0x3FFF_FFFF:
                raise SdoAbortedError(ABORT['value range'])
        elif subindex == 2 and (241 <= value <= 253):
            raise SdoAbortedError(ABORT['value range'])
