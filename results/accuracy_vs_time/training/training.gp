$S0 << EOD
2.221 17.8569 250.0
4.424 19.345 500.0
7.609 19.7368 750.0
13.104 23.4734 1000.0
EOD
$S1 << EOD
2.347 17.9561 250.0
4.541 19.4914 500.0
7.532 20.7587 750.0
13.909 23.7035 1000.0
25.724 25.3829 1250.0
41.882 25.524 1500.0
EOD
$S2 << EOD
2.294 18.0119 250.0
4.348 19.5723 500.0
6.962 22.2096 750.0
12.525 24.0743 1000.0
23.5 25.5902 1250.0
39.822 26.3698 1500.0
59.63 26.3076 1750.0
84.666 26.558 2000.0
EOD
$S3 << EOD
2.561 18.0656 250.0
4.741 19.6503 500.0
7.851 21.7866 750.0
13.798 25.4395 1000.0
25.004 25.1927 1250.0
41.372 26.038 1500.0
62.362 24.5355 1750.0
86.768 24.0073 2000.0
115.457 24.1249 2250.0
145.049 24.2682 2500.0
177.122 24.2499 2750.0
209.194 24.3665 3000.0
EOD
$S4 << EOD
2.186 18.0656 250.0
4.217 19.6503 500.0
6.259 20.3007 750.0
8.318 20.6398 1000.0
10.448 21.1172 1250.0
12.567 21.3733 1500.0
14.65 21.7222 1750.0
16.701 21.8975 2000.0
18.808 22.1393 2250.0
20.887 22.4678 2500.0
23.021 22.4678 2750.0
25.25 22.6956 3000.0
EOD
$S5 << EOD
2.278 18.0656 250.0
4.358 19.6503 500.0
7.148 21.7866 750.0
12.684 25.4395 1000.0
20.644 26.3901 1250.0
28.592 26.6561 1500.0
37.027 26.7384 1750.0
44.888 26.7197 2000.0
52.115 26.8707 2250.0
59.211 26.9622 2500.0
67.187 26.9551 2750.0
74.326 27.0649 3000.0
EOD
$E4 << EOD
13.104 23.4734 1000.0
41.882 25.524 1500.0
84.666 26.558 2000.0
209.194 24.3665 3000.0
25.25 22.6956 3000.0
74.326 27.0649 3000.0
EOD
$F4 << EOD
2.186 18.0656 250.0
4.217 19.6503 500.0
6.259 20.3007 750.0
6.962 22.2096 750.0
12.525 24.0743 1000.0
12.684 25.4395 1000.0
20.644 26.3901 1250.0
28.592 26.6561 1500.0
37.027 26.7384 1750.0
52.115 26.8707 2250.0
59.211 26.9622 2500.0
74.326 27.0649 3000.0
EOD
$S8 << EOD
4.85 16.9577 250.0
9.32 18.457 500.0
13.951 19.1745 750.0
22.96 22.7804 1000.0
EOD
$S9 << EOD
4.87 17.0903 250.0
9.117 18.7114 500.0
13.568 21.5319 750.0
24.277 24.3268 1000.0
42.056 25.0456 1250.0
66.784 25.9445 1500.0
99.012 26.1767 1750.0
133.436 26.3653 2000.0
EOD
$S10 << EOD
4.55 17.14 250.0
8.312 18.8101 500.0
12.708 20.8685 750.0
21.868 24.3933 1000.0
39.053 25.6157 1250.0
63.531 26.5012 1500.0
96.344 26.6864 1750.0
131.15 26.9855 2000.0
171.204 27.2188 2250.0
214.338 27.4679 2500.0
263.233 27.4368 2750.0
312.631 27.5496 3000.0
EOD
$E2 << EOD
22.96 22.7804 1000.0
133.436 26.3653 2000.0
312.631 27.5496 3000.0
EOD
$F2 << EOD
4.55 17.14 250.0
8.312 18.8101 500.0
12.708 20.8685 750.0
13.568 21.5319 750.0
21.868 24.3933 1000.0
39.053 25.6157 1250.0
63.531 26.5012 1500.0
96.344 26.6864 1750.0
131.15 26.9855 2000.0
171.204 27.2188 2250.0
214.338 27.4679 2500.0
312.631 27.5496 3000.0
EOD
set terminal pngcairo size 1000,960 font ",10" noenhanced
set output "results/accuracy_vs_time/training/training.png"
set multiplot layout 2,1 title "3DGS training on demo_scene: held-out PSNR against wall time"
set xlabel "training wall time (s, training steps only, 1 thread)"
set ylabel "held-out PSNR (dB)"
set grid
set key outside right
set title "1/4 resolution (held-out PSNR against ground truth at 1/4)"
plot $S0 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/4 res, 1000 it", \
  $S1 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/4 res, 1500 it", \
  $S2 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/4 res, 2000 it", \
  $S3 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/4 res, 3000 it", \
  $S4 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 3 title "1/4 res, 3000 it, no densification", \
  $S5 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 2 title "1/4 res, 3000 it, densify until 1000", \
  $E4 using 1:2 with points pt 5 ps 1.1 lc rgb "black" title "end of a run", \
  $F4 using 1:2 with lines dt 2 lw 1 lc rgb "black" notitle, \
  $F4 using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb "red" title "Pareto front (this resolution)", \
  $F4 using 1:2:(sprintf("%d", $3)) with labels offset 0,1.1 font ",8" notitle
set title "1/2 resolution (held-out PSNR against ground truth at 1/2)"
plot $S8 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/2 res, 1000 it", \
  $S9 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/2 res, 2000 it", \
  $S10 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 1 title "1/2 res, 3000 it", \
  $E2 using 1:2 with points pt 5 ps 1.1 lc rgb "black" title "end of a run", \
  $F2 using 1:2 with lines dt 2 lw 1 lc rgb "black" notitle, \
  $F2 using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb "red" title "Pareto front (this resolution)", \
  $F2 using 1:2:(sprintf("%d", $3)) with labels offset 0,1.1 font ",8" notitle
unset multiplot
