// Buffer ids that instrumented shaders put in their trace records (trace_record.h), shared by C++ (the
// trace file's buffer table) and GLSL. Images are addressed by logical texel offset.
#ifndef HP_TRACE_BUFFERS_H
#define HP_TRACE_BUFFERS_H

#define HP_TBUF_NODES 0u
#define HP_TBUF_POSITIONS 1u
#define HP_TBUF_INDICES 2u
#define HP_TBUF_SOUP 3u
#define HP_TBUF_OBJECT_FIRST 4u
#define HP_TBUF_SLOT_SCENE 5u
#define HP_TBUF_NORMALS 6u
#define HP_TBUF_SOUP_NORMALS 7u
#define HP_TBUF_SLOT_MATERIAL 8u
#define HP_TBUF_MATERIALS 9u
#define HP_TBUF_GBUF_DEPTH 10u
#define HP_TBUF_GBUF_NORMAL 11u
#define HP_TBUF_SHADOW_MASK 12u
#define HP_TBUF_REFLECTION 13u
#define HP_TBUF_COMPACT_RAYS 14u
#define HP_TBUF_SORT_KEYS 15u
#define HP_TBUF_SORT_VALUES 16u
#define HP_TBUF_RAY_COUNT 17u
// The radix sort's own buffers (shaders/sort/): the ping-pong halves and the per-block histograms.
#define HP_TBUF_SORT_SCRATCH_KEYS 18u
#define HP_TBUF_SORT_SCRATCH_VALUES 19u
#define HP_TBUF_SORT_HISTOGRAMS 20u
#define HP_TBUF_COUNT 21u

#endif
