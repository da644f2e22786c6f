// Radix sort geometry, shared by the GLSL kernels (shaders/sort/) and the C++ host
// (renderer/passes/radix_sort.cpp) so both size blocks and histograms the same way.
//
// 4-bit digits: the scatter's stable local ranking keeps one counter per (digit, thread) in shared
// memory; 16 digits x 256 threads x 4 B = 16 KiB fits the 32 KiB lavapipe limit with room to spare,
// while 256 digits would need 256 KiB. A 32-bit key therefore takes 8 passes, a 30-bit Morton code 8,
// a 6-bit octant/direction key 2.
#ifndef HP_SORT_RADIX_CONFIG_H
#define HP_SORT_RADIX_CONFIG_H

#define RADIX_BITS 4u
#define RADIX_DIGITS 16u
#define RADIX_THREADS 256u
// Each thread of a block owns RADIX_ITEMS consecutive elements in the scatter (that is what makes the
// local ranking stable without subgroup operations).
#define RADIX_ITEMS 16u
#define RADIX_BLOCK (RADIX_THREADS * RADIX_ITEMS)

#endif
