"""The tactile camera: frame sources (OpenCV), area extraction, and the reading chain.

Importing this package imports OpenCV; keep it out of light code paths.
"""
from .extract import AreaExtractor
from .pipeline import FramePipeline, FrameRejected, Reading
from .read import CameraReading, read_source
from .source import FrameReader, open_source, write_video

__all__ = ["AreaExtractor", "FramePipeline", "FrameRejected", "Reading", "CameraReading", "read_source", "FrameReader", "open_source",
           "write_video"]
