// Survey with loops (RepeatFor, RepeatUntil).
// Drone1 flies three 4 m survey lanes (RepeatFor); at the same time Drone2
// steps 2 m east at a time until it is more than 5 m east of its start
// (RepeatUntil, checked before every step: it stops after three steps),
// then its Exit block brings it back. Both land when both are done.
package SurveyRepeat

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Survey() {
	PAR_Arm()
	PAR_Takeoff()
	PAR_Survey()
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

func PAR_Survey() {
	SEQ_Lanes()
	RepeatUntil(Drone2.Y() > 5, SEQ_Step, SEQ_Back)
}

func SEQ_Lanes() {
	RepeatFor(3, SEQ_Lane)
	Drone1.FlyToXYZ(0, 0, 3)
}

func SEQ_Lane() {
	Drone1.FlyByX(4)
	Drone1.FlyByY(1)
	Drone1.FlyByX(-4)
	Drone1.FlyByY(1)
}

func SEQ_Step() {
	Drone2.FlyByY(2)
	Drone2.TurnOnCamera()
	Drone2.PauseFor(1)
}

func SEQ_Back() {
	Drone2.FlyToXYZ(0, 0, 5)
}

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
