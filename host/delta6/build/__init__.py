"""Compilers: one cached compile helper (compilecache), the portable core built natively for
ctypes, AVR images with Debian's avr-gcc, the firmware application recipe."""
