#include "cf.h"

void cf_init(cf_t *s, float dt, float alpha)
{
    s->dt = dt;
    s->alpha = alpha;
    s->oma = 1.0f - alpha;
    s->theta = 0.0f;
    s->n = 0u;
}

void cf_update(cf_t *s, float rate, float angle)
{
    s->n++;
    /* FAULT */
    s->theta = s->alpha * (s->theta + rate * s->dt) + s->oma * angle;
}
