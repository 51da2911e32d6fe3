/* blocks.c: the element registry, from blocks/blocks.def. */
#include <ctype.h>
#include <string.h>

#include "gen.h"

#define BLOCK(id, kw, letter, nnodes, args, keys, ready, desc) \
    [id] = {kw, letter, nnodes, args, keys, ready, desc},
const BlockDesc block_desc[BK_COUNT] = {
#include "../blocks/blocks.def"
};
#undef BLOCK

int block_by_keyword(const char *s, int len) {
    for (int i = 0; i < BK_COUNT; i++) {
        const char *kw = block_desc[i].keyword;
        if (kw && (int)strlen(kw) == len && !strncmp(kw, s, (size_t)len))
            return i;
    }
    return -1;
}

int block_by_letter(char c) {
    for (int i = 0; i < BK_COUNT; i++)
        if (block_desc[i].letter && block_desc[i].letter == toupper((unsigned char)c))
            return i;
    return -1;
}

bool block_has_key(int kind, const char *key) {
    const char *k = block_desc[kind].keys;
    size_t n = strlen(key);
    while (*k) {
        const char *e = strchr(k, ' ');
        size_t len = e ? (size_t)(e - k) : strlen(k);
        if (len == n && !strncmp(k, key, n))
            return true;
        if (!e)
            break;
        k = e + 1;
    }
    return false;
}
