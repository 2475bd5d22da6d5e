"""psrt: the console entry point, where the tracer's commands and the viewer's meet.

tracer/ never imports viewer/; this package imports both (see psrt/cli.py).
"""
