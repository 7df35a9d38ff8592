#include <hindsight/engine/deterministic_math.h>

#include <sleef.h>

// Sleef_cinz_*d1_u10purec: scalar, pure C, no FMA, deterministic, 1.0-ulp bound (SLEEF 3.5's naming:
// "c" no FMA, "inz" deterministic). See the header for why these and not glibc's.
namespace hindsight::dmath {

double sin(double x) { return Sleef_cinz_sind1_u10purec(x); }
double cos(double x) { return Sleef_cinz_cosd1_u10purec(x); }
void sincos(double x, double* sine, double* cosine) {
  const Sleef_double_2 sc = Sleef_cinz_sincosd1_u10purec(x);
  *sine = sc.x;
  *cosine = sc.y;
}
double asin(double x) { return Sleef_cinz_asind1_u10purec(x); }
double exp(double x) { return Sleef_cinz_expd1_u10purec(x); }
double log2(double x) { return Sleef_cinz_log2d1_u10purec(x); }
double pow(double x, double y) { return Sleef_cinz_powd1_u10purec(x, y); }
double tanh(double x) { return Sleef_cinz_tanhd1_u10purec(x); }

}  // namespace hindsight::dmath
