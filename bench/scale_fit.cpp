// Times the scale fit of lights seen only saturated (fitClippedScales, product/clipped_light_scale.h)
// on synthetic texels and prints its answers in hex, so that two builds can be compared for speed
// and for bit-identical results. Per object a constant albedo; per texel random direct terms D_c
// (one per light) and R, both lobes, I = a (s.D + R) + s.G + G_R at the scales below with 5%
// log-normal noise, and a diagonal covariance.
// Usage: scale_fit_bench [LIGHTS=3] [OBJECTS=30] [TEXELS_PER_OBJECT=400]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "product/clipped_light_scale.h"

int main(int argc, char** argv) {
  using namespace relume;
  const int K = argc > 1 ? std::atoi(argv[1]) : 3, objects = argc > 2 ? std::atoi(argv[2]) : 30,
            perObject = argc > 3 ? std::atoi(argv[3]) : 400;
  const std::vector<double> truth = {1.5, 1.2, 0.9, 1.1, 1.3, 0.8, 1.0, 1.4};
  if (K < 1 || K > static_cast<int>(truth.size()) || objects < 1 || perObject < 1) {
    std::fprintf(stderr, "scale_fit_bench: LIGHTS in 1..%zu, OBJECTS and TEXELS_PER_OBJECT >= 1\n", truth.size());
    return 2;
  }
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> noise(0, 1);
  std::vector<ScaleTexel> texels;
  for (int o = 0; o < objects; ++o) {
    const double albedo = 0.2 + 0.7 * u(rng);
    for (int i = 0; i < perObject; ++i) {
      ScaleTexel t;
      t.object = o;
      t.mean.resize(K + 1);
      t.specular.resize(K + 1);
      double received = 0.05 + 0.2 * u(rng), specular = 0.01 * u(rng);
      t.mean[K] = received;
      for (int c = 0; c < K; ++c) {
        const double place = u(rng);  // how directly the light reaches this texel
        t.mean[c] = place * place * (0.3 + (o % (c + 2)) * 0.2) * u(rng);
        t.specular[c] = 0.02 * u(rng) * t.mean[c];
        received += truth[c] * t.mean[c];
        specular += truth[c] * t.specular[c];
      }
      t.specular[K] = 0.01 * u(rng);
      t.shown = albedo * received * std::exp(0.05 * noise(rng)) + specular;
      const size_t n = 2 * (K + 1);
      t.covariance.assign(n * n, 0.0);
      for (size_t a = 0; a < n; ++a) t.covariance[a * n + a] = 1e-5 * (1 + u(rng));
      texels.push_back(std::move(t));
    }
  }
  const auto start = std::chrono::steady_clock::now();
  const ScaleFit fit = fitClippedScales(texels, 32, 0.2);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (int c = 0; c < K; ++c)
    std::printf("light %d: scale %a (%.4f, truth %.2f), log error %a, group %d\n", c, fit.scale[c], fit.scale[c],
                truth[c], fit.logError[c], fit.groupOf.empty() ? -1 : fit.groupOf[c]);
  for (const auto& [o, s] : fit.perObject) std::printf("%d:%a ", o, s);
  std::printf("\nseconds %.2f\n", seconds);
}
