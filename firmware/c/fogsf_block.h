/*
 * fogsf calibration block: one unit's model as data in flash, read without a copy.
 *
 * `fogsf export MODEL --blob unit.bin` writes the block (docs/firmware.md, "Calibration
 * block"): a little-endian, position-independent image of a fogsf_model whose tables are
 * reached by offsets from the block's start, with a format version, its total length, the
 * model's sizes, a CRC-32 of the header and one of the payload. One firmware image then
 * serves every unit of a line: the line writes each unit's block into a flash sector and the
 * firmware calls fogsf_model_from_block on it at power-on.
 *
 * Layout (every word a uint32 least significant byte first, floats as their float32 bits):
 *   0 magic "FSFB"   4 block version   8 total length   12 header length   16 tables T
 *  20 payload CRC (bytes [header length, total length))  24 model format version
 *  28 K  32 F  36 L  40 H  44 D  48 stuck samples  52 lstm inputs  56 quad_diag
 *  60 feat_diag  64 P  68 sample_dt_s  72 t_ref  76 t_min  80 t_max  84 head_b
 *  88 out_scale  92 out_offset  96 bias_b  100 crc32_sizes  104 crc32 (the model's own)
 * 108 T entries {offset, length in bytes}, slot t = FOGSF_BLOCK_T_*; offset 0 = absent
 * 108 + 8 T: header CRC (bytes [0, 108 + 8 T)); header length = 112 + 8 T.
 * A future optional table is one more slot: an older loader refuses a block that fills a
 * slot it does not know (FOGSF_BLOCK_UNKNOWN_TABLE) rather than run without it. The rate
 * part is such a pair (a model of format FOGSF_FORMAT_VERSION_RATE): its three words R, Q
 * and the bits of 1/FS in slot RATE_HEAD, its rate_w in slot RATE_W; a block without it
 * declares T = 17 (the slots through META), one with it T = 19.
 */
#ifndef FOGSF_BLOCK_H
#define FOGSF_BLOCK_H

#include "fogsf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FOGSF_BLOCK_MAGIC 0x42465346u   /* the bytes 'F' 'S' 'F' 'B' */
#define FOGSF_BLOCK_VERSION 1u          /* this layout */
#define FOGSF_BLOCK_HEAD_BYTES 108u     /* the header before the table directory */
#define FOGSF_BLOCK_MAX_TABLES 64u      /* directory slots a block may declare */

/* Table slots (the directory's order; the payload holds them in this order, 4-aligned). */
#define FOGSF_BLOCK_T_MODEL_ID 0u       /* 16 hex digits and a NUL: 17 bytes */
#define FOGSF_BLOCK_T_FILTER_ALPHA 1u   /* [K]; absent when K = 0 */
#define FOGSF_BLOCK_T_FEAT_W 2u         /* [F][1+K+P], [F] with feat_diag */
#define FOGSF_BLOCK_T_FEAT_B 3u         /* [F] */
#define FOGSF_BLOCK_T_LSTM_W 4u         /* layer 0 [4H][N], then layers 1.. [4H][H] */
#define FOGSF_BLOCK_T_LSTM_R 5u         /* [L][4H][H] */
#define FOGSF_BLOCK_T_LSTM_B 6u         /* [L][8H] */
#define FOGSF_BLOCK_T_HEAD_W 7u         /* [H] */
#define FOGSF_BLOCK_T_SKIP_W 8u         /* [F] */
#define FOGSF_BLOCK_T_QUAD_W 9u         /* [F][F] ([F] with quad_diag); optional, with cube_w */
#define FOGSF_BLOCK_T_CUBE_W 10u        /* [F]; optional, with quad_w */
#define FOGSF_BLOCK_T_BIAS_W 11u        /* [F]; the bias head: the three or none */
#define FOGSF_BLOCK_T_BIAS_QUAD_W 12u   /* [F] */
#define FOGSF_BLOCK_T_BIAS_CUBE_W 13u   /* [F] */
#define FOGSF_BLOCK_T_PLAY_HALF_C 14u   /* [P]; present when P > 0 */
#define FOGSF_BLOCK_T_PLAY_SOURCE_W 15u /* [P][1+K]; present when P > 0 */
#define FOGSF_BLOCK_T_META 16u          /* the artifact's stream.json (bytes): not read here */
#define FOGSF_BLOCK_T_RATE_HEAD 17u     /* R, Q, 1/FS bits (3 words); with the rate part */
#define FOGSF_BLOCK_T_RATE_W 18u        /* [R][Q]; with the rate part */
#define FOGSF_BLOCK_N_TABLES 19u        /* the slots this loader knows */

/* Why a block was refused: one reason each, the first check that failed. The structure is
 * checked against n before any table is read, then the two CRCs, then the model. */
typedef enum fogsf_block_status {
    FOGSF_BLOCK_OK = 0,
    FOGSF_BLOCK_NULL = 1,            /* blk or out NULL */
    FOGSF_BLOCK_TRUNCATED = 2,       /* n below the header, the header length or the total */
    FOGSF_BLOCK_BAD_MAGIC = 3,       /* not "FSFB" */
    FOGSF_BLOCK_BAD_VERSION = 4,     /* a block version other than FOGSF_BLOCK_VERSION */
    FOGSF_BLOCK_BAD_LENGTH = 5,      /* T above the maximum, header length not 112 + 8 T,
                                        total below it or not a multiple of 4 */
    FOGSF_BLOCK_MODEL_VERSION = 6,   /* model format version not FOGSF_FORMAT_VERSION or
                                        FOGSF_FORMAT_VERSION_RATE */
    FOGSF_BLOCK_TOO_LARGE = 7,       /* K, F, L, H, P or the rate part's R beyond
                                        FOGSF_MAX_* */
    FOGSF_BLOCK_BAD_SIZES = 8,       /* F, L, H or D zero, N > F, quad_diag or feat_diag
                                        not 0/1, feat_diag with F != 1+K+P; R or Q zero,
                                        Q above FOGSF_RATE_COEFS_LIMIT */
    FOGSF_BLOCK_MISALIGNED = 9,      /* blk or a table offset not a multiple of 4 */
    FOGSF_BLOCK_OFFSET_RANGE = 10,   /* a table outside [header length, total length) */
    FOGSF_BLOCK_OVERLAP = 11,        /* two tables share a byte */
    FOGSF_BLOCK_TABLE_LENGTH = 12,   /* a table's length is not what the sizes give */
    FOGSF_BLOCK_TABLE_MISSING = 13,  /* a table the sizes need is absent (the rate part's
                                        two with format 7), or one of a pair (quad/cube,
                                        the bias head's three, the plays') */
    FOGSF_BLOCK_UNKNOWN_TABLE = 14,  /* a slot at or past FOGSF_BLOCK_N_TABLES is filled */
    FOGSF_BLOCK_HEADER_CRC = 15,     /* the header's CRC-32 differs */
    FOGSF_BLOCK_PAYLOAD_CRC = 16,    /* the payload's CRC-32 differs */
    FOGSF_BLOCK_MODEL_ID = 17,       /* the id is not 16 lowercase hex digits and a NUL */
    FOGSF_BLOCK_MODEL_REFUSED = 18   /* fogsf_model_check refuses the model (its own CRCs,
                                        a non-finite play) */
} fogsf_block_status;

/* A model read from a block: the fogsf_model (pass &bm.model to fogsf_init and fogsf_step)
 * and what its pointers need besides the block, the per-layer table pointers and the bias
 * head and plays structs. Its pointers point into the block and into this struct: keep both
 * in place (static) while the model is used; never copy it. */
typedef struct fogsf_block_model {
    fogsf_model model;
    const float *lstm_w[FOGSF_MAX_LAYERS];
    const float *lstm_r[FOGSF_MAX_LAYERS];
    const float *lstm_b[FOGSF_MAX_LAYERS];
    fogsf_bias_head bias;
    fogsf_plays plays;
} fogsf_block_model;

/* Reads the block blk[0 .. n) (n may exceed its total length: a flash sector) into *out
 * without copying a table: *out's pointers point into blk, which must be 4-byte aligned and
 * stay in place. Checks, in order, the header and every table's offset, length and
 * alignment against n and the sizes (FOGSF_MAX_*) before it reads a table, then the header
 * and payload CRCs, the model id, and fogsf_model_check on the model it filled. Returns
 * FOGSF_BLOCK_OK, or the reason of the first check that failed; *out (when not NULL) is
 * zeroed first, so a refused block leaves a model fogsf_init refuses (MODEL_INVALID). Fields
 * of fogsf_model this loader does not know stay zero (NULL: absent). */
fogsf_block_status fogsf_model_from_block(const uint8_t *blk, size_t n,
                                          fogsf_block_model *out);

#ifdef __cplusplus
}
#endif

#endif
