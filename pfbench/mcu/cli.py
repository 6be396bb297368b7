"""``pfbench mcu ...``: Cortex-M4 cost model commands."""
from __future__ import annotations

import click


@click.group()
def mcu():
    """Cortex-M4 (STM32F4) time, energy and memory predictions."""


try:  # the emulator commands live beside the emulator (optional toolchain)
    from .emulate_cli import emulate as _emulate
except ModuleNotFoundError as _exc:  # pragma: no cover - until the emulator lands
    if _exc.name != f"{__package__}.emulate_cli":
        raise
else:
    mcu.add_command(_emulate)
