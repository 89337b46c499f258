* demo.s -- a small fwemu demo program (run it with: fwemu exec isa/demo/demo.s)
*
* Sorts a table of signed words in place (insertion sort), then computes
*   D0.L = sum of the sorted words (sign-extended),
*   D1.W = a rotate-and-xor checksum of the sorted table,
*   D2.L = sum of squares (MULS),
*   D3.L = the median word (sign-extended),
* and stops with TRAP #0. The data sits in the data section, so the sort writes to RAM.

COUNT   equ     (table_end-table)/2     ; number of words in the table

        section code
start:  lea     table,a0                ; A0 -> first word
        moveq   #1,d4                   ; D4 = i, the next element to insert
.outer  cmpi.w  #COUNT,d4
        bge.s   .sorted
        move.w  d4,d5
        add.w   d5,d5                   ; D5 = 2*i (byte offset)
        move.w  0(a0,d5.w),d6           ; D6 = key = table[i]
.inner  tst.w   d5                      ; while j > 0 and table[j-1] > key
        beq.s   .place
        move.w  -2(a0,d5.w),d7
        cmp.w   d6,d7
        ble.s   .place
        move.w  d7,0(a0,d5.w)           ;   table[j] = table[j-1]
        subq.w  #2,d5
        bra.s   .inner
.place  move.w  d6,0(a0,d5.w)           ; table[j] = key
        addq.w  #1,d4
        bra.s   .outer

.sorted moveq   #0,d0                   ; sum
        moveq   #0,d1                   ; checksum
        moveq   #0,d2                   ; sum of squares
        move.w  #COUNT-1,d4             ; DBRA counter
        movea.l a0,a1
.sum    move.w  (a1)+,d6
        ext.l   d6
        add.l   d6,d0
        rol.w   #3,d1                   ; checksum = rol(checksum, 3) ^ word
        eor.w   d6,d1
        move.w  d6,d7
        muls    d7,d7                   ; 16x16 -> 32 signed
        add.l   d7,d2
        dbra    d4,.sum

        move.w  #COUNT/2,d5             ; median: table[COUNT/2]
        lsl.w   #1,d5
        move.w  0(a0,d5.w),d3
        ext.l   d3
        trap    #0

        section data
table:  dc.w    907,-12,33,4096,-2048,0,77,-1,15000,250,-32768,32767,5
table_end:
