/* avr-libc's own float multiply under another name, for tests/sim/test_fast_mulsf3.py: what
 * its __mulsf3 does (mulsf3.o: the product, then the rounding), so that a check image that
 * links firmware/src/fast_mulsf3.S still has the original to compare with. */
#if defined(__AVR__)
	.text
	.global	delta6_reference_mulsf3
	.type	delta6_reference_mulsf3, @function
delta6_reference_mulsf3:
	call	__mulsf3x
	jmp	__fp_round
	.size	delta6_reference_mulsf3, . - delta6_reference_mulsf3
#endif
