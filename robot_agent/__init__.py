"""The robot agent: camera data -> patient -> classified frames -> a stream the hospital trusts.

Imports only the domain package ``vigil`` (plus numpy, onnxruntime, websockets, OpenCV,
pydantic-settings and, optionally, MediaPipe)."""

__version__ = "0.1.0"
