"""The ONNX boundary, seen from training: a trained run -> the two model files the engine runs.

Modules:
    to_onnx -- export with torch-vs-ONNX-Runtime parity checks and optional int8 quantisation
               (the engine's side of the contract is :mod:`engine.contract`)

Import the submodules directly; importing this package loads nothing heavy.
"""
