// Every control structure in one mission, with conditions chosen so that each
// drone's action order does not depend on timing (thresholds lie between the
// points the drones stop at): a bare PauseFor on the ground station, PAR/SEQ,
// If both ways, RepeatFor/Until/While, DoUntil interrupting its body (the
// third FlyByX is cancelled, Exit runs), DoWhile whose body completes (Exit
// skipped), WaitUntil, WaitWhile, PauseWhile and PauseUntil across drones.
package EveryStructure

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
	PauseFor(1)
	PAR_Arm()
	PAR_Takeoff()
	If(Drone1.Z() > 2, SEQ_High, SEQ_Low)
	If(Drone2.Battery() < 10, SEQ_Empty, SEQ_Full)
	PAR_Loops()
	DoUntil(Drone1.X() > 5, SEQ_Creep, SEQ_Hold)
	DoWhile(Drone2.Z() > 1, SEQ_Lower, SEQ_Never)
	PAR_Waits()
	PAR_Land()
}

func PAR_Arm() {
	Drone1.Arm()
	Drone2.Arm()
}

func PAR_Takeoff() {
	Drone1.Takeoff(3)
	Drone2.Takeoff(5)
}

func SEQ_High() { Drone1.TurnOnCamera() }

func SEQ_Low() { Drone1.Land() }

func SEQ_Empty() { Drone2.Land() }

func SEQ_Full() { Drone2.TurnOnCamera() }

func PAR_Loops() {
	SEQ_Lanes()
	SEQ_Steps()
}

func SEQ_Lanes() {
	RepeatFor(2, SEQ_Lane)
	Drone1.FlyToXYZ(0, 0, 3)
}

func SEQ_Lane() { Drone1.FlyByY(1) }

func SEQ_Steps() {
	RepeatUntil(Drone2.Y() > 3, SEQ_East, SEQ_Back)
	RepeatWhile(Drone2.X() < 1.5, SEQ_North, SEQ_Back)
}

func SEQ_East() { Drone2.FlyByY(2) }

func SEQ_North() { Drone2.FlyByX(1) }

func SEQ_Back() { Drone2.FlyToXYZ(0, 0, 5) }

func SEQ_Creep() {
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
	Drone1.FlyByX(2)
}

func SEQ_Hold() {
	Drone1.PauseFor(1)
	Drone1.FlyToXYZ(0, 0, 3)
}

func SEQ_Lower() { Drone2.FlyByZ(-1) }

func SEQ_Never() { Drone2.Land() }

func PAR_Waits() {
	SEQ_Lead()
	SEQ_Follow()
}

func SEQ_Lead() {
	Drone1.FlyByY(4)
	Drone1.PauseWhile(Drone2.Y() < 3)
	Drone1.FlyToXYZ(0, 0, 3)
}

func SEQ_Follow() {
	WaitUntil(Drone1.Y() > 3, SEQ_Go)
	WaitWhile(Drone1.Y() > 1, SEQ_Home)
	Drone2.PauseUntil(Drone1.Y() < 1.5)
}

func SEQ_Go() { Drone2.FlyByY(4) }

func SEQ_Home() { Drone2.FlyToXYZ(0, 0, 4) }

func PAR_Land() {
	SEQ_Land1()
	SEQ_Land2()
}

func SEQ_Land1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Land2() {
	Drone2.Land()
	Drone2.Disarm()
}
