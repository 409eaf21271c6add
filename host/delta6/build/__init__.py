"""Compilers: the portable core built natively for ctypes, AVR images with Debian's avr-gcc, the firmware application recipe."""
