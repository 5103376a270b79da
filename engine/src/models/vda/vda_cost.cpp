#include "models/vda/vda_cost.hpp"

namespace dvs {

VdaFlops vda_window_flops(const VdaConfig& c, int64_t frames, int64_t input_h, int64_t input_w) {
  const double T = double(frames), ps = c.patch_size;
  const double h = double(input_h / c.patch_size), w = double(input_w / c.patch_size), hw = h * w;
  const double N = 1 + hw, D = c.embed_dim, M = c.mlp_hidden_dim, F = c.features, F2 = c.output_conv1_out;
  auto linear = [](double rows, double in, double out) { return 2 * rows * in * out; };
  auto conv = [](double pixels, double in, double out, double k) { return 2 * pixels * in * out * k * k; };
  VdaFlops f;
  // A ViT block per frame: qkv, scores and context (every head together: N x N x D each), projection, MLP.
  f.encoder_block = linear(N, D, 3 * D) + 2 * (2 * N * N * D) + linear(N, D, D) + linear(N, D, M) + linear(N, M, D);
  f.encoder = T * (conv(hw, 3, D, ps) + c.depth * f.encoder_block);

  // The head's maps: layer1 at 4x the patch grid, layer2 at 2x, layer3 at 1x, layer4 at 1/2 (stride-2 conv).
  const auto& oc = c.out_channels;
  const double P1 = 16 * hw, P2 = 4 * hw, P3 = hw, P4 = double((input_h / c.patch_size + 1) / 2) * double((input_w / c.patch_size + 1) / 2);
  const double Pf = double(input_h) * double(input_w);
  double head = 0;
  for (int i = 0; i < 4; ++i) head += linear(hw, D, oc[size_t(i)]);                 // projections
  head += linear(hw, oc[0], oc[0] * 16) + linear(hw, oc[1], oc[1] * 4);            // transposed convs (k = 4, 2)
  head += conv(P4, oc[3], oc[3], 3);                                               // layer4's stride-2 conv
  const double rn_in[4] = {double(oc[0]), double(oc[1]), double(oc[2]), double(oc[3])}, P[4] = {P1, P2, P3, P4};
  for (int i = 0; i < 4; ++i) head += conv(P[i], rn_in[i], F, 3);                  // layer*_rn
  const double rcu = 2 * conv(1, F, F, 3);                                         // per pixel: two 3x3 convs
  head += P4 * rcu + conv(P3, F, F, 1);                                            // refinenet4 (one unit)
  head += 2 * P3 * rcu + conv(P2, F, F, 1);                                        // refinenet3
  head += 2 * P2 * rcu + conv(P1, F, F, 1);                                        // refinenet2
  head += 2 * P1 * rcu + conv(4 * P1, F, F, 1);                                    // refinenet1 (to 2x)
  head += conv(4 * P1, F, F2, 3) + conv(Pf, F2, 32, 3) + conv(Pf, 32, 1, 1);       // output convolutions
  // A temporal module per position and frame: proj_in, two attention blocks (q, k, v, out; scores and context
  // over T frames), the GEGLU feed-forward (C -> 4C twice, 4C -> C), proj_out.
  auto temporal = [&](double C, double positions) {
    const double per_token = linear(1, C, C) + 2 * (4 * linear(1, C, C) + 2 * 2 * T * C) + 2 * linear(1, C, 4 * C) +
                             linear(1, 4 * C, C) + linear(1, C, C);
    return positions * per_token;
  };
  head += temporal(oc[2], P3) + temporal(oc[3], P4) + temporal(F, P3) + temporal(F, P2);
  f.head = T * head;
  return f;
}

}  // namespace dvs
