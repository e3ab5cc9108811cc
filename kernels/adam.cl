// adam.cl: one fused Adam step over a model's flat parameter buffer (Kingma & Ba 2015), with decoupled
// weight decay (Loshchilov & Hutter 2019, "AdamW"). Scalars that depend on the step (learning rate after
// decay, bias corrections) are computed on the host, so the step needs no readback.
//
//   m = b1 m + (1 - b1) g,   v = b2 v + (1 - b2) g^2
//   p -= lr * ( (m / c1) / (sqrt(v / c2) + eps) + wd * p ),   c1 = 1 - b1^t,  c2 = 1 - b2^t
// guard[0]: the step's loss; when it is not finite (NaN/Inf) the step changes nothing, so one bad batch
// cannot poison the parameters or the moments.
__kernel void adam_step(const uint n, const float lr, const float beta1, const float beta2, const float epsilon,
                        const float weight_decay, const float inv_c1, const float inv_c2,
                        __global float* restrict params, __global const float* restrict grads,
                        __global float* restrict m, __global float* restrict v, __global const float* restrict guard) {
  const size_t i = get_global_id(0);
  if (i >= n || !isfinite(guard[0])) return;
  const float g = grads[i];
  const float mi = fma(beta1, m[i], (1.0f - beta1) * g);
  const float vi = fma(beta2, v[i], (1.0f - beta2) * g * g);
  m[i] = mi;
  v[i] = vi;
  const float p = params[i];
  const float update = (mi * inv_c1) / (sqrt(vi * inv_c2) + epsilon);
  params[i] = p - lr * fma(weight_decay, p, update);
}
