"""Cortex-M4 (STM32F4) cost model and emulation.

* ``counting``/``cycles``/``costmodel``: predict time and energy from operation counts of the
  real algorithm (embedded paper, Tables 2-3);
* ``c/`` + ``toolchain``/``emulate``: the same filter in C, cross-compiled for a Cortex-M4F and
  run in an emulator to count executed instructions.
"""
