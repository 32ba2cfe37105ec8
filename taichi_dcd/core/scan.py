"""Exclusive prefix sums inside a kernel: how a parallel loop's output lands in one order.

A loop whose iterations append a varying number of items writes each iteration's count, the
counts are scanned into offsets, and each iteration's items go to its offset: the order of a
serial loop appending in iteration order, on any number of threads and on a GPU.
"""

import taichi as ti

# Blocks a scan is cut into (scanned side by side); the length of its block_sum array.
SCAN_BLOCKS = 256


def block_sums():
    """The scratch array exclusive_scan needs: SCAN_BLOCKS int32."""
    return ti.ndarray(ti.i32, shape=SCAN_BLOCKS)


@ti.func
def exclusive_scan(values: ti.template(), first: ti.i32, n: ti.i32, block_sum: ti.template(),
                   serial: ti.template()) -> ti.i32:
    """Replace the integer counts values[first .. first + n) by their exclusive prefix sums
    and return their total. The counts are cut into block_sum.shape[0] blocks, each scanned
    on its own (side by side, or serially with `serial`), then offset by the scan of the
    blocks' totals. Call it at a kernel's top level, so that its loops are the kernel's own."""
    n_blocks = block_sum.shape[0]
    size = (n + n_blocks - 1) // n_blocks
    ti.loop_config(serialize=serial)
    for k in range(n_blocks):
        running = 0
        for i in range(first + k * size, first + ti.min((k + 1) * size, n)):
            count = values[i]
            values[i] = running
            running += count
        block_sum[k] = running
    total = 0
    ti.loop_config(serialize=True)
    for k in range(n_blocks):
        block_total = block_sum[k]
        block_sum[k] = total
        total += block_total
    ti.loop_config(serialize=serial)
    for i in range(n):
        values[first + i] += block_sum[i // size]
    return total
