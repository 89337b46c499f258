"""A true subset of the Motorola MC68000: instruction table, assembler, encoder, disassembler and a cycle-exact interpreter."""
