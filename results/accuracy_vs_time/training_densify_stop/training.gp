$S0 << EOD
2.284 17.9561 250.0
4.433 19.4914 500.0
6.99 20.7587 750.0
12.41 23.7035 1000.0
19.298 24.7517 1250.0
26.297 24.8883 1500.0
EOD
$S1 << EOD
2.245 18.0119 250.0
4.44 19.5723 500.0
6.995 22.2096 750.0
12.193 24.0743 1000.0
18.827 25.4621 1250.0
25.338 26.0521 1500.0
31.953 26.2875 1750.0
38.55 26.3595 2000.0
EOD
$E4 << EOD
26.297 24.8883 1500.0
38.55 26.3595 2000.0
EOD
$F4 << EOD
2.245 18.0119 250.0
4.433 19.4914 500.0
4.44 19.5723 500.0
6.99 20.7587 750.0
6.995 22.2096 750.0
12.193 24.0743 1000.0
18.827 25.4621 1250.0
25.338 26.0521 1500.0
31.953 26.2875 1750.0
38.55 26.3595 2000.0
EOD
$S4 << EOD
4.23 17.0903 250.0
7.688 18.7114 500.0
11.747 21.5319 750.0
19.688 24.3268 1000.0
29.676 25.4297 1250.0
39.51 25.7675 1500.0
49.773 25.9321 1750.0
59.901 25.9581 2000.0
EOD
$S5 << EOD
4.593 17.14 250.0
8.207 18.8101 500.0
12.376 20.8685 750.0
20.519 24.3933 1000.0
31.112 25.7778 1250.0
41.309 26.1838 1500.0
52.232 26.4081 1750.0
62.919 26.4816 2000.0
73.174 26.6521 2250.0
83.348 26.769 2500.0
94.474 26.8018 2750.0
105.574 26.7959 3000.0
EOD
$E2 << EOD
59.901 25.9581 2000.0
105.574 26.7959 3000.0
EOD
$F2 << EOD
4.23 17.0903 250.0
4.593 17.14 250.0
7.688 18.7114 500.0
8.207 18.8101 500.0
11.747 21.5319 750.0
19.688 24.3268 1000.0
20.519 24.3933 1000.0
29.676 25.4297 1250.0
31.112 25.7778 1250.0
41.309 26.1838 1500.0
52.232 26.4081 1750.0
62.919 26.4816 2000.0
73.174 26.6521 2250.0
83.348 26.769 2500.0
94.474 26.8018 2750.0
EOD
set terminal pngcairo size 1000,960 font ",10" noenhanced
set output "results/accuracy_vs_time/training_densify_stop/training.png"
set multiplot layout 2,1 title "3DGS training on demo_scene: held-out PSNR against wall time"
set xlabel "training wall time (s, training steps only, 1 thread)"
set ylabel "held-out PSNR (dB)"
set grid
set key outside right
set title "1/4 resolution (held-out PSNR against ground truth at 1/4)"
plot $S0 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 2 title "1/4 res, 1500 it, densify until 1000", \
  $S1 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 2 title "1/4 res, 2000 it, densify until 1000", \
  $E4 using 1:2 with points pt 5 ps 1.1 lc rgb "black" title "end of a run", \
  $F4 using 1:2 with lines dt 2 lw 1 lc rgb "black" notitle, \
  $F4 using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb "red" title "Pareto front (this resolution)", \
  $F4 using 1:2:(sprintf("%d", $3)) with labels offset 0,1.1 font ",8" notitle
set title "1/2 resolution (held-out PSNR against ground truth at 1/2)"
plot $S4 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 2 title "1/2 res, 2000 it, densify until 1000", \
  $S5 using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt 2 title "1/2 res, 3000 it, densify until 1000", \
  $E2 using 1:2 with points pt 5 ps 1.1 lc rgb "black" title "end of a run", \
  $F2 using 1:2 with lines dt 2 lw 1 lc rgb "black" notitle, \
  $F2 using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb "red" title "Pareto front (this resolution)", \
  $F2 using 1:2:(sprintf("%d", $3)) with labels offset 0,1.1 font ",8" notitle
unset multiplot
