"""Simulators: the natively compiled simulated device (delta6sim://), the virtual board in simavr, AVR benchmarks."""
