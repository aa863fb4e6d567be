// Event handler (Whenever): each time Drone1 is far out on a low battery,
// dip 1 m and come back up, then go on with the interrupted leg.
// Drone1 patrols 20 m north and back three times while Drone2 hovers
// for a minute nearby.  The condition is watched as telemetry arrives (never polled);
// each time it *becomes* true, Drone1's running leg is cancelled (it holds),
// SEQ_Dip runs, and the leg is re-issued for what is left of it.  Drone2 is
// not in the Handler: it is never interrupted.  With the default battery
// model the charge stays above 80 % and the Handler never runs; with
// tests/virtual/fast_drain.toml (Drone1 drains 60 % a minute) it runs twice.
package WheneverBattery

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Up()
	Whenever(Drone1.Battery() < 80 && Drone1.X() > 15, SEQ_Dip)
	PAR_Patrol()
	PAR_Down()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(3)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
}

func PAR_Patrol() {
	RepeatFor(3, SEQ_Leg)
	Drone2.PauseFor(60)
}

func SEQ_Leg() {
	Drone1.FlyByX(20)
	Drone1.FlyByX(-20)
}

func SEQ_Dip() {
	Drone1.FlyByZ(-1)
	Drone1.FlyByZ(1)
}

func PAR_Down() {
	SEQ_Down1()
	SEQ_Down2()
}

func SEQ_Down1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Down2() {
	Drone2.Land()
	Drone2.Disarm()
}
