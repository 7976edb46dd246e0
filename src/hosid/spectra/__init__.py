"""Windows, blocks and higher-order spectral domains."""

from .blocks import BlockLayout, block_fft, block_means, choose_layout
from .domains import DOMAINS, bispectral_domain, trispectral_domain
from .windows import WINDOWS, Window, get_window

__all__ = [
    "DOMAINS",
    "WINDOWS",
    "BlockLayout",
    "Window",
    "bispectral_domain",
    "block_fft",
    "block_means",
    "choose_layout",
    "get_window",
    "trispectral_domain",
]
