"""`planter commission`: find each row's drive, check it against the machine file, set its
polarity, home it, measure its phase offset and write the machine file (issue 22 item 2)."""

from .procedure import (CommissionError, Observer, RowFindings, SimulatedObserver,
                        checklist, commission_machine, commission_row, updated_machine)

__all__ = ['CommissionError', 'Observer', 'RowFindings', 'SimulatedObserver', 'checklist',
           'commission_machine', 'commission_row', 'updated_machine']
