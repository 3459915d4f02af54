# SPDX-License-Identifier: BSD-2-Clause
"""The packaging toolchain: what turns the FMU scripts of ``fmu_src/`` into self-contained FMUs.

``build`` (pythonfmu, then the shim, the bundled runtime and the normalized archive), ``fmi3``
(the FMI 3.0 twins), ``runtime`` (the pinned CPython the FMUs carry), ``licences`` and
``controller_doc`` (what goes into ``documentation/``) and ``shim/`` (the C layer between a host
and pythonfmu). (The exported scenarios' C runtime is the engine's, ``orchestrator/native/``.) The
models themselves,
and the scripts that declare them, live one level up; nothing here runs inside an FMU.
"""
