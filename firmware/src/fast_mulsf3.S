/*
 * The float multiply (__mulsf3, which avr-gcc calls for every float product) with a fast path:
 * two normal operands whose product is normal take one pass here (unpack, the 24-by-24-bit
 * product in nine MULs, round to nearest even, pack), about 105 cycles with the call instead
 * of about 137 through avr-libc's __mulsf3x and __fp_round (three calls, a generic unpacking
 * and normalisation). Everything else (zero, subnormal, infinite or NaN operands, a product
 * outside the normal range) goes through avr-libc's own sequence, so every result is the
 * one avr-libc gives, bit for bit (tests/sim/test_fast_mulsf3.py compares the two in simavr).
 * The calibrated solve makes about 140 products a sample.
 *
 * avr-gcc's calling convention: A in r25:r22, B in r21:r18, the product in r25:r22; r18-r27,
 * r30, r31 and r0 are free to use, r1 must be zero on return.
 */
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)

	.text
	/* The general case, avr-libc's sequence (its mulsf3.o); before the entry, within the
	   checks' branch range. */
.Lslow:
	call	__mulsf3x
	jmp	__fp_round

	.global	__mulsf3
	.type	__mulsf3, @function
__mulsf3:
	/* Exponents minus one: r27 = ea - 1, r26 = eb - 1; 254 or 255 (ea or eb 0 or 255) is
	   not a normal operand. */
	mov	r27, r24
	lsl	r27		/* C = the exponent's low bit */
	mov	r27, r25
	rol	r27
	subi	r27, 1
	cpi	r27, 254
	brsh	.Lslow
	mov	r26, r20
	lsl	r26
	mov	r26, r21
	rol	r26
	subi	r26, 1
	cpi	r26, 254
	brsh	.Lslow
	/* The product's exponent before normalisation, E = ea + eb - 127 = r26 + r27 - 125, in
	   r27:r26; the result's is E or E + 1. Outside 1..253 the result may not be normal. */
	add	r26, r27
	ldi	r27, 0
	adc	r27, r27
	subi	r26, 125
	sbci	r27, 0
	tst	r27		/* (sbci's Z covers both bytes) */
	brne	.Lslow		/* E < 0 or E > 255 */
	cpi	r26, 254
	brsh	.Lslow
	tst	r26
	breq	.Lslow
	/* E fits one byte now (r27 is 0). The sign in T; the hidden bits. */
	eor	r21, r25
	bst	r21, 7
	ori	r24, 0x80
	ori	r20, 0x80
	/* P = A B (a2 a1 a0 = r24 r23 r22, b2 b1 b0 = r20 r19 r18), 48 bits p5..p0: p0 | p1 in
	   r30 (only their sticky bit is kept), p1 r31, p2 r21, p3 r25, p4 r27, p5 r22 (once a0
	   is done with). First A b0: 32 bits, no carry beyond p3. */
	mul	r22, r18	/* a0 b0 */
	movw	r30, r0
	eor	r21, r21
	eor	r25, r25
	mul	r23, r18	/* a1 b0 */
	add	r31, r0
	adc	r21, r1
	mul	r24, r18	/* a2 b0 */
	add	r21, r0
	adc	r25, r1
	eor	r18, r18	/* b0 done: the zero register from here */
	mul	r22, r19	/* a0 b1 */
	add	r31, r0
	adc	r21, r1
	adc	r25, r18
	adc	r27, r18
	or	r30, r31	/* p1 is final: the sticky bits of p1 and p0 */
	mul	r22, r20	/* a0 b2 */
	add	r21, r0
	adc	r25, r1
	adc	r27, r18
	mul	r23, r19	/* a1 b1: the sum so far stays below 2^34, no carry beyond p4 */
	add	r21, r0
	adc	r25, r1
	adc	r27, r18
	eor	r22, r22	/* a0 done: p5 */
	mul	r24, r19	/* a2 b1 */
	add	r25, r0
	adc	r27, r1
	adc	r22, r18
	mul	r23, r20	/* a1 b2 */
	add	r25, r0
	adc	r27, r1
	adc	r22, r18
	mul	r24, r20	/* a2 b2 */
	add	r27, r0
	adc	r22, r1
	eor	r1, r1
	/* Normalise: P in [2^46, 2^48). The mantissa is p5 p4 p3 (r22 r27 r25), the guard byte
	   p2 (r21): its top bit the guard bit, the rest and r30 the sticky bits. */
	sbrc	r22, 7
	rjmp	.Ltop
	lsl	r21
	rol	r25
	rol	r27
	rol	r22
	rjmp	.Lround
.Ltop:
	inc	r26
.Lround:
	/* Round to nearest, ties to even (as __fp_round). */
	sbrs	r21, 7
	rjmp	.Lpack
	andi	r21, 0x7F
	or	r21, r30
	brne	.Lup
	sbrs	r25, 0
	rjmp	.Lpack
.Lup:
	subi	r25, 0xFF
	sbci	r27, 0xFF
	sbci	r22, 0xFF
	brmi	.Lpack
	ldi	r22, 0x80	/* 0xFFFFFF rounded up: 1.0 of the next binade (only unnormalised P) */
	inc	r26
.Lpack:
	/* sign | E << 23 | the mantissa without its hidden bit. */
	mov	r24, r22
	mov	r23, r27
	mov	r22, r25
	lsl	r24
	mov	r25, r26
	lsr	r25
	ror	r24
	bld	r25, 7
	ret
	.size	__mulsf3, . - __mulsf3

#endif
