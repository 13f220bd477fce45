"""go2vlm: make a Unitree Go2 see with a vision-language model and act on what it sees."""

__version__ = "0.1.0"
